//! Noise identification by spline fitting (paper §8.1): Σ_z and Σ_q from a
//! recording of the moving robot.
//!
//! Each channel (a joint of `joints.csv`, an axis of `imu.csv`) is fitted by
//! least squares with a cubic spline over time (eq. (20)); the motion is
//! smooth at the knot scale, the noise is white, so the residual variance
//! corrected for the fit's degrees of freedom, RSS/(N − m), estimates σ².
//!
//! The knot spacing is chosen from the data, separately per channel: starting
//! from [`NoiseOptions::start_spacing`] it is halved while halving still
//! explains significantly more of the signal. The test is the nested-model F
//! statistic F = ((RSS_h − RSS_{h/2})/Δm) / (RSS_{h/2}/(N − m_{h/2})), which
//! is 1 ± √(2/Δm) when the coarser spline already follows the motion; a
//! refinement counts as significant when F exceeds 1 + z√(2/Δm). At the first
//! insignificant halving the finer fit is used (it captures the motion, and
//! dividing by N − m keeps σ² unbiased however many knots it spends). Why not
//! a fixed spacing: too coarse a spline leaves motion in the residuals (σ too
//! large), and the right spacing depends on the motion's bandwidth, which the
//! F test measures. Why not generalized cross-validation: GCV picks the
//! spacing that predicts best, which may leave a small bias of the motion in
//! the residuals; the F test asks directly whether any is left that the data
//! can detect (with N = 14 400 samples and Δm ≈ 500, below 1 % of σ²).

use std::path::Path;

use serde::{Deserialize, Serialize};

use robimu_model::noise::NoiseModel;
use robimu_model::observations::Measurements;
use robimu_model::{JointState, Knots, Spline, SplineError};
use robimu_session::{toml_error, NoiseOverride, NoiseShape, SessionError, IMU_COLUMNS};

use crate::noise_id::{
    identify_channel_with, ChannelIdentification, IdOptions, Identification, NoiseIdError,
};

/// Settings of the spacing search.
#[derive(Debug, Clone)]
pub struct NoiseOptions {
    /// Spline degree.
    pub degree: usize,
    /// Coarsest knot spacing tried, s.
    pub start_spacing: f64,
    /// Fewest samples per knot span (limits the finest spacing).
    pub min_samples_per_span: f64,
    /// z of the F test (standard deviations above 1).
    pub significance: f64,
}

impl Default for NoiseOptions {
    /// Cubic, from 2 s down to 4 samples per span, z = 3.
    fn default() -> Self {
        Self {
            degree: 3,
            start_spacing: 2.0,
            min_samples_per_span: 4.0,
            significance: 3.0,
        }
    }
}

/// The noise estimate of one channel.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelNoise {
    /// σ, the channel's unit.
    pub sigma: f64,
    /// Standard error of σ (Gaussian noise: σ/√(2(N − m))).
    pub std_error: f64,
    /// Knot spacing of the fit used, s.
    pub spacing: f64,
    /// Samples N.
    pub samples: usize,
    /// Spline coefficients m.
    pub coeffs: usize,
    /// Whether the spacing search converged (false: it reached the finest
    /// spacing while refining still helped, so σ may include motion).
    pub resolved: bool,
}

/// Σ_z and Σ_q of a recording.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseEstimate {
    /// `[ax, ay, az, gx, gy, gz]` (m/s², rad/s).
    pub sigma_z: [ChannelNoise; 6],
    /// One per joint, rad.
    pub sigma_q: Vec<ChannelNoise>,
}

impl NoiseEstimate {
    /// The estimate as a `[noise]` table (session.toml's format).
    pub fn to_override(&self) -> NoiseOverride {
        NoiseOverride {
            sigma_z: Some(std::array::from_fn(|c| self.sigma_z[c].sigma)),
            sigma_q: Some(self.sigma_q.iter().map(|c| c.sigma).collect()),
        }
    }
}

/// Why the noise could not be estimated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NoiseError {
    /// Too few samples for a spline fit with residual degrees of freedom.
    #[error("{channel}: {count} samples are too few to estimate the noise (need at least {need})")]
    TooFewSamples {
        /// The channel.
        channel: String,
        /// Samples present.
        count: usize,
        /// Samples needed.
        need: usize,
    },
    /// Times or values not finite, or no time span.
    #[error("{channel}: {message}")]
    BadSamples {
        /// The channel.
        channel: String,
        /// What is wrong.
        message: String,
    },
    /// The search settings are unusable.
    #[error("bad noise-search setting: {0}")]
    BadOptions(String),
    /// A spline fit failed.
    #[error("{channel}: spline fit failed: {source}")]
    Spline {
        /// The channel.
        channel: String,
        /// The cause.
        source: SplineError,
    },
    /// The identification of a channel's correlation failed.
    #[error(transparent)]
    Identification(#[from] NoiseIdError),
}

/// The spline fit at spacing h.
fn fit_spline(
    t: &[f64],
    y: &[f64],
    span: (f64, f64),
    h: f64,
    degree: usize,
) -> Result<Spline, SplineError> {
    let knots = Knots::uniform(span.0, span.1, h, degree)?;
    Spline::fit(knots, 1, t, y)
}

/// The residuals y − spline(t).
fn spline_residuals(spline: &Spline, t: &[f64], y: &[f64]) -> Result<Vec<f64>, SplineError> {
    let mut js = JointState::default();
    t.iter()
        .zip(y)
        .map(|(&ti, &yi)| {
            spline.evaluate(ti, &mut js)?;
            Ok(yi - js.q[0])
        })
        .collect()
}

/// A fit at spacing h: (RSS, m).
fn fit_rss(
    t: &[f64],
    y: &[f64],
    span: (f64, f64),
    h: f64,
    degree: usize,
) -> Result<(f64, usize), SplineError> {
    let spline = fit_spline(t, y, span, h, degree)?;
    let m = spline.knots().num_coeffs();
    let rss = spline_residuals(&spline, t, y)?.iter().map(|r| r * r).sum();
    Ok((rss, m))
}

/// σ of one channel `y` sampled at `t` (see the module doc for the rule).
pub(crate) fn channel_noise(
    channel: &str,
    t: &[f64],
    y: &[f64],
    opts: &NoiseOptions,
) -> Result<ChannelNoise, NoiseError> {
    if !(opts.start_spacing.is_finite()
        && opts.start_spacing > 0.0
        && opts.min_samples_per_span >= 1.0
        && opts.significance.is_finite())
    {
        return Err(NoiseError::BadOptions(format!("{opts:?}")));
    }
    let bad = |message: String| NoiseError::BadSamples {
        channel: channel.to_string(),
        message,
    };
    if t.len() != y.len() {
        return Err(bad(format!("{} times but {} values", t.len(), y.len())));
    }
    let n = t.len();
    let need = 4 * (opts.degree + 1);
    if n < need {
        return Err(NoiseError::TooFewSamples {
            channel: channel.to_string(),
            count: n,
            need,
        });
    }
    if let Some(i) = (0..n).find(|&i| !(t[i].is_finite() && y[i].is_finite())) {
        return Err(bad(format!("sample {} is not finite", i + 1)));
    }
    let span = t
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let duration = span.1 - span.0;
    if duration <= 0.0 {
        return Err(bad("all samples are at the same time".into()));
    }
    let spline_err = |source| NoiseError::Spline {
        channel: channel.to_string(),
        source,
    };
    let h_min = opts.min_samples_per_span * duration / n as f64;
    let mut h = opts.start_spacing.min(duration / 2.0).max(h_min);
    let (mut rss, mut m) = fit_rss(t, y, span, h, opts.degree).map_err(spline_err)?;
    let mut resolved = false;
    while h / 2.0 >= h_min {
        let (rss2, m2) = fit_rss(t, y, span, h / 2.0, opts.degree).map_err(spline_err)?;
        if m2 + 1 >= n {
            break;
        }
        let dm = m2.saturating_sub(m).max(1) as f64;
        let s2 = rss2 / (n - m2) as f64;
        let f = if s2 > 0.0 {
            (rss - rss2) / dm / s2
        } else {
            f64::INFINITY
        };
        (rss, m, h) = (rss2, m2, h / 2.0);
        if f < 1.0 + opts.significance * (2.0 / dm).sqrt() {
            resolved = true;
            break;
        }
    }
    let dof = (n - m).max(1) as f64;
    let sigma = (rss / dof).sqrt();
    Ok(ChannelNoise {
        sigma,
        std_error: sigma / (2.0 * dof).sqrt(),
        spacing: h,
        samples: n,
        coeffs: m,
        resolved,
    })
}

/// Σ_z and Σ_q of `data` (n joints), each channel by [`channel_noise`].
pub fn estimate_noise(
    data: &Measurements,
    n: usize,
    opts: &NoiseOptions,
) -> Result<NoiseEstimate, NoiseError> {
    if data.joint_q.len() != data.joint_t.len() * n {
        return Err(NoiseError::BadSamples {
            channel: "joints".into(),
            message: format!(
                "{} values are not {} joints × {} samples",
                data.joint_q.len(),
                n,
                data.joint_t.len()
            ),
        });
    }
    let mut sigma_q = Vec::with_capacity(n);
    for j in 0..n {
        let y: Vec<f64> = data.joint_q.iter().skip(j).step_by(n).copied().collect();
        sigma_q.push(channel_noise(
            &format!("q{}", j + 1),
            &data.joint_t,
            &y,
            opts,
        )?);
    }
    let mut z = Vec::with_capacity(6);
    for (c, name) in IMU_COLUMNS.iter().enumerate() {
        let y: Vec<f64> = data.imu_z.iter().map(|v| v[c]).collect();
        z.push(channel_noise(name, &data.imu_t, &y, opts)?);
    }
    let sigma_z: [ChannelNoise; 6] = z.try_into().expect("six IMU channels");
    Ok(NoiseEstimate { sigma_z, sigma_q })
}

/// The time span of `t` (finite samples assumed).
fn span_of(t: &[f64]) -> (f64, f64) {
    t.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        })
}

/// The residuals of the spline fit of `y` at spacing `h`, and the fit's
/// imprint on white noise (lags 0..=`lags`): for unit white noise the
/// residuals' autocovariances are δ_k − imprint_k, here averaged over
/// [`IMPRINT_DRAWS`] draws fitted with the same knots at the same times.
fn residuals_and_imprint(
    channel: &str,
    t: &[f64],
    y: &[f64],
    h: f64,
    degree: usize,
    lags: usize,
) -> Result<(Vec<f64>, Vec<f64>), NoiseError> {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let spline_err = |source| NoiseError::Spline {
        channel: channel.to_string(),
        source,
    };
    let span = span_of(t);
    let spline = fit_spline(t, y, span, h, degree).map_err(spline_err)?;
    let r = spline_residuals(&spline, t, y).map_err(spline_err)?;
    let n = t.len();
    let mut imprint = vec![0.0; lags + 1];
    let mut rng = rand::rngs::StdRng::seed_from_u64(0x1A7E_5EED);
    for _ in 0..IMPRINT_DRAWS {
        let e: Vec<f64> = (0..n).map(|_| StandardNormal.sample(&mut rng)).collect();
        let s = fit_spline(t, &e, span, h, degree).map_err(spline_err)?;
        let w = spline_residuals(&s, t, &e).map_err(spline_err)?;
        // δ_k − c_k(w), with the draw's own c_k(e) for δ_k (a control
        // variate: the same draw's sampling error largely cancels)
        for (k, v) in imprint.iter_mut().enumerate() {
            let ce: f64 = (k..n).map(|i| e[i] * e[i - k]).sum::<f64>() / n as f64;
            let cw: f64 = (k..n).map(|i| w[i] * w[i - k]).sum::<f64>() / n as f64;
            *v += (ce - cw) / IMPRINT_DRAWS as f64;
        }
    }
    Ok((r, imprint))
}

/// White draws averaged for a fit's imprint.
const IMPRINT_DRAWS: usize = 4;

/// ‖q̈‖² at the IMU sample times, from each joint's spline at the spacing
/// the noise search chose for it (clamped to the joints' time span).
fn joint_acceleration2(
    data: &Measurements,
    n: usize,
    est: &NoiseEstimate,
    opts: &NoiseOptions,
) -> Result<Vec<f64>, NoiseError> {
    let mut out = vec![0.0; data.imu_t.len()];
    let span = span_of(&data.joint_t);
    let mut js = JointState::default();
    for j in 0..n {
        let name = format!("q{}", j + 1);
        let y: Vec<f64> = data.joint_q.iter().skip(j).step_by(n).copied().collect();
        let spline = fit_spline(&data.joint_t, &y, span, est.sigma_q[j].spacing, opts.degree)
            .map_err(|source| NoiseError::Spline {
                channel: name,
                source,
            })?;
        for (o, &t) in out.iter_mut().zip(&data.imu_t) {
            spline.evaluate_clamped(t, &mut js);
            *o += js.qdd[0] * js.qdd[0];
        }
    }
    Ok(out)
}

/// The noise model of one IMU channel from its spline residuals.
///
/// Any fit removes the noise's slow part: the residuals of white noise are
/// themselves correlated at the knot scale (a spline of m coefficients takes
/// m/N of their variance, below the knot frequency), so the AR is fitted to
/// autocovariances corrected by the fit's imprint on white noise
/// ([`identify_channel_with`]), and white channels come out white.
///
/// Limitation: the knot search of [`channel_noise`] cannot tell correlated
/// noise from motion (slow noise power makes every refinement look
/// significant), so on a correlated channel it refines to its finest
/// spacing and the spline absorbs most of the slow noise. The channel is
/// then reliably flagged as correlated (Ljung–Box, order > 0), but its
/// correlation time, N_eff and σ are not recovered from these residuals:
/// take them from a calibration's residuals, where the model has far fewer
/// parameters than a spline.
fn identify_spline_channel(
    channel: &str,
    t: &[f64],
    y: &[f64],
    spacing: f64,
    qdd2: &[f64],
    opts: &NoiseOptions,
    id_opts: &IdOptions,
) -> Result<ChannelIdentification, NoiseError> {
    let lags = id_opts.lags.max(id_opts.max_order);
    let (r, imprint) = residuals_and_imprint(channel, t, y, spacing, opts.degree, lags)?;
    Ok(identify_channel_with(
        channel,
        t,
        &r,
        Some(qdd2),
        id_opts,
        Some(&imprint),
    )?)
}

/// The noise model of the six IMU channels (AR correlation, motion level,
/// whiteness; [`crate::noise_id`]) from the residuals of the spline fits of
/// `est` (corrected for the spline's imprint on white noise; see
/// [`identify_spline_channel`] for what these residuals cannot tell), with
/// the motion regressor ‖q̈‖² from the joint splines.
pub fn identify_imu_noise(
    data: &Measurements,
    n: usize,
    est: &NoiseEstimate,
    opts: &NoiseOptions,
    id_opts: &IdOptions,
) -> Result<Identification, NoiseError> {
    let qdd2 = joint_acceleration2(data, n, est, opts)?;
    let mut channels = Vec::with_capacity(6);
    for (c, name) in IMU_COLUMNS.iter().enumerate() {
        let y: Vec<f64> = data.imu_z.iter().map(|v| v[c]).collect();
        channels.push(identify_spline_channel(
            name,
            &data.imu_t,
            &y,
            est.sigma_z[c].spacing,
            &qdd2,
            opts,
            id_opts,
        )?);
    }
    Ok(Identification::from_channels(channels))
}

/// A noise file: a TOML document whose `[noise]` table has session.toml's
/// format (other keys are ignored).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoiseFile {
    /// The `[noise]` table.
    pub noise: NoiseOverride,
}

impl NoiseFile {
    /// Read `path` and check that every σ is a positive number.
    pub fn read(path: &Path) -> Result<Self, SessionError> {
        Ok(Self::read_with_shape(path)?.0)
    }

    /// Read `path` once: its σ (checked as [`Self::read`]) and its `[noise]`
    /// table's optional `ar_z`/`motion_z` ([`NoiseShape::parse`], validated;
    /// `None` when it has neither).
    pub fn read_with_shape(path: &Path) -> Result<(Self, Option<NoiseShape>), SessionError> {
        let text =
            robimu_model::text::read_to_string(path).map_err(|e| SessionError::io(path, e))?;
        let file: Self = toml::from_str(&text).map_err(|e| toml_error(path, &text, &e))?;
        file.noise.validate(path)?;
        let shape = NoiseShape::parse(&text, path)?;
        Ok((file, shape))
    }

    /// The TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a noise table always serialises")
    }

    /// The TOML text with the noise model's correlation and motion level as
    /// optional keys of `[noise]`: `ar_z` (per IMU channel the AR
    /// coefficients φ_1…φ_p, an empty list when white) and `motion_z` (per
    /// channel the motion gain c of σ²(t) = σ² + c‖q̈‖²).
    pub fn to_toml_with_model(&self, model: &NoiseModel) -> String {
        let mut doc = toml::Table::try_from(self).expect("a noise table always serialises");
        let table = doc
            .get_mut("noise")
            .and_then(toml::Value::as_table_mut)
            .expect("the [noise] table");
        let ar: Vec<toml::Value> = model
            .imu
            .iter()
            .map(|c| toml::Value::Array(c.ar.phi().iter().map(|&v| v.into()).collect()))
            .collect();
        let motion: Vec<toml::Value> = model.imu.iter().map(|c| c.motion.into()).collect();
        table.insert("ar_z".into(), toml::Value::Array(ar));
        table.insert("motion_z".into(), toml::Value::Array(motion));
        toml::to_string(&doc).expect("a noise table always serialises")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise_id::IdOptions;
    use crate::simulate::{random_session, SimulateOptions};
    use robimu_model::Robot;

    /// Every channel within 10 % of the σ it was simulated with, and the
    /// reported standard error consistent with the actual error.
    fn check(opts: &SimulateOptions, seed: u64) {
        let robot = Robot::aubo_i5();
        let s = random_session(&robot, 120.0, 1.0, opts, seed).unwrap();
        let est = estimate_noise(&s.data, robot.dof(), &NoiseOptions::default()).unwrap();
        let pairs = est
            .sigma_z
            .iter()
            .zip(opts.sigma_z)
            .chain(est.sigma_q.iter().zip(opts.sigma_q.iter().copied()));
        for (k, (e, truth)) in pairs.enumerate() {
            let rel = e.sigma / truth - 1.0;
            eprintln!(
                "channel {k}: est {:.4e} true {:.4e} ({:+.2} %, se {:.2} %), h = {} s, resolved {}",
                e.sigma,
                truth,
                100.0 * rel,
                100.0 * e.std_error / truth,
                e.spacing,
                e.resolved
            );
            assert!(e.resolved, "channel {k}: {e:?}");
            assert!(rel.abs() < 0.10, "channel {k}: {e:?} vs {truth}");
            assert!(e.std_error > 0.0 && e.std_error < 0.02 * truth);
            assert!(
                (e.sigma - truth).abs() < 4.0 * e.std_error,
                "channel {k}: the standard error understates the error"
            );
        }
    }

    #[test]
    fn recovers_the_papers_noise() {
        check(&SimulateOptions::paper(&Robot::aubo_i5()), 3);
    }

    #[test]
    fn recovers_noise_scaled_on_some_channels() {
        let mut opts = SimulateOptions::paper(&Robot::aubo_i5());
        for c in [0, 4, 5] {
            opts.sigma_z[c] *= 2.0;
        }
        for j in [1, 3] {
            opts.sigma_q[j] *= 2.0;
        }
        check(&opts, 11);
    }

    #[test]
    fn pure_noise_and_a_smooth_signal() {
        // A polynomial (inside the spline space) plus known noise: the
        // search stops at once and σ comes out within its standard error.
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let noise = Normal::new(0.0, 0.3).unwrap();
        let t: Vec<f64> = (0..6000).map(|i| i as f64 / 100.0).collect();
        let y: Vec<f64> = t
            .iter()
            .map(|&t| 2.0 + 0.5 * t - 0.01 * t * t + noise.sample(&mut rng))
            .collect();
        let e = channel_noise("y", &t, &y, &NoiseOptions::default()).unwrap();
        assert!(e.resolved);
        assert!((e.sigma - 0.3).abs() < 3.0 * e.std_error, "{e:?}");
        // A fast sine needs fine knots; a fixed coarse spacing would fail.
        let y: Vec<f64> = t
            .iter()
            .map(|&t| (2.0 * t).sin() * 5.0 + noise.sample(&mut rng))
            .collect();
        let e = channel_noise("y", &t, &y, &NoiseOptions::default()).unwrap();
        assert!(e.resolved && e.spacing < 1.0, "{e:?}");
        assert!((e.sigma - 0.3).abs() < 4.0 * e.std_error, "{e:?}");
    }

    /// Noise-free motion plus AR(1) accelerometer noise of correlation time
    /// 30 ms and white gyroscope and joint noise: the accelerometer channels
    /// are flagged as correlated, the gyroscope channels come out white
    /// (order 0, Ljung–Box not rejecting) despite the spline's imprint.
    #[test]
    fn identifies_correlated_accelerometer_noise() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let robot = Robot::aubo_i5();
        let mut opts = SimulateOptions::paper(&robot);
        opts.noise = false;
        let mut s = random_session(&robot, 120.0, 1.0, &opts, 21).unwrap();
        let paper = SimulateOptions::paper(&robot);
        let dt = 1.0 / paper.imu_rate;
        let tc = 0.03;
        let ar =
            robimu_model::noise::ArNoise::new(vec![(-dt / tc).exp()], paper.sigma_z[0]).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(4);
        let mut normal = || -> f64 { StandardNormal.sample(&mut rng) };
        let mut u = [0.0; 3];
        for (i, z) in s.data.imu_z.iter_mut().enumerate() {
            let (a, scale) = ar.whitening(i);
            for c in 0..3 {
                let pred = a.first().map_or(0.0, |a| a * u[c]);
                u[c] = pred + normal() / scale;
                z[c] += u[c] * paper.sigma_z[c] / paper.sigma_z[0];
            }
            for c in 3..6 {
                z[c] += paper.sigma_z[c] * normal();
            }
        }
        let nq = robot.dof();
        for (k, q) in s.data.joint_q.iter_mut().enumerate() {
            *q += paper.sigma_q[k % nq] * normal();
        }
        let o = NoiseOptions::default();
        let est = estimate_noise(&s.data, nq, &o).unwrap();
        for (c, e) in est.sigma_z.iter().enumerate() {
            eprintln!("spline {c}: {e:?} (true σ {:.3e})", paper.sigma_z[c]);
        }
        let id = identify_imu_noise(&s.data, nq, &est, &o, &IdOptions::default()).unwrap();
        let want = ar.correlation_time(dt);
        for c in &id.channels {
            eprintln!(
                "{}: p = {} φ = {:?} T = {:.1} ms (true {:.1}) σ = {:.3e} c = {:.2e} LB p = {:.2e}",
                c.channel,
                c.order,
                c.phi,
                1e3 * c.correlation_time_s,
                1e3 * want,
                c.sigma,
                c.motion,
                c.ljung_box_p
            );
        }
        for c in 0..3 {
            let ch = &id.channels[c];
            assert!(
                !id.white[c] && ch.order > 0 && ch.ljung_box_p < 1e-6,
                "{ch:?}"
            );
        }
        for c in 3..6 {
            assert!(
                id.white[c] && id.channels[c].order == 0,
                "{:?}",
                id.channels[c]
            );
        }
        let text = NoiseFile {
            noise: est.to_override(),
        }
        .to_toml_with_model(&id.model);
        let doc: toml::Table = toml::from_str(&text).unwrap();
        let ar_z = doc["noise"]["ar_z"].as_array().unwrap();
        assert_eq!(ar_z.len(), 6);
        assert!(ar_z[3].as_array().unwrap().is_empty());
        assert_eq!(doc["noise"]["motion_z"].as_array().unwrap().len(), 6);
    }

    #[test]
    fn bad_input_is_named() {
        let o = NoiseOptions::default();
        let e = channel_noise("gx", &[0.0, 1.0], &[0.0, 1.0], &o).unwrap_err();
        assert!(e.to_string().contains("gx: 2 samples"), "{e}");
        let t: Vec<f64> = (0..100).map(f64::from).collect();
        let mut y = vec![0.0; 100];
        y[7] = f64::NAN;
        let e = channel_noise("q2", &t, &y, &o).unwrap_err();
        assert!(e.to_string().contains("q2: sample 8"), "{e}");
        let e = channel_noise("q2", &[1.0; 100], &[0.0; 100], &o).unwrap_err();
        assert!(e.to_string().contains("same time"), "{e}");
    }

    #[test]
    fn noise_file_round_trip_and_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("noise.toml");
        let file = NoiseFile {
            noise: NoiseOverride {
                sigma_z: Some([0.1, 0.2, 0.3, 0.01, 0.02, 0.03]),
                sigma_q: Some(vec![1e-4, 2e-4]),
            },
        };
        std::fs::write(&path, file.to_toml()).unwrap();
        assert_eq!(NoiseFile::read(&path).unwrap(), file);
        // the same table parses as session.toml's [noise]
        let meta = format!(
            "format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\n{}",
            file.to_toml()
        );
        let m = robimu_session::SessionMeta::parse(&meta, &path).unwrap();
        assert_eq!(m.noise, Some(file.noise.clone()));
        std::fs::write(&path, "[noise]\nsigma_q = [1e-4, -2]\n").unwrap();
        let e = NoiseFile::read(&path).unwrap_err();
        assert!(e.to_string().contains("-2"), "{e}");
        std::fs::write(&path, "x = 1\n").unwrap();
        let e = NoiseFile::read(&path).unwrap_err();
        assert!(e.to_string().contains("noise"), "{e}");
    }
}
