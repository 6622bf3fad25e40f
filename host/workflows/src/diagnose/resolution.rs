//! The time resolution of an effect that has one (`bias_drift`'s number of
//! spline segments M, docs/model.md §4.7), chosen from the data when the
//! effect wins a round of the diagnosis.
//!
//! Each M ∈ {1, 2, 4, …, M_max} is scored at the current fit (the Rao score
//! S_M of [`super::score`], k_M parameters; no refit) and the one with the
//! smallest
//!
//! ```text
//! AIC_M = −S_M + 2 k_M
//! ```
//!
//! is taken: the score approximates the likelihood-ratio statistic of the
//! refit, so this is the refits' AIC comparison without the refits. The
//! nested bases (a piecewise-linear spline on M segments is one on 2M) make
//! S_M non-decreasing in M; the penalty keeps the finer bases out unless
//! the drift has structure at their scale. AIC, not BIC (k ln N): a real
//! drift (a random walk, a warm-up) has no finite resolution, and for a
//! truth outside the candidates AIC picks the best predicting one
//! (Shibata 1980) while BIC stops too coarse. Measured
//! (`host/cli/tests/drift.rs`, 300 s, a random walk of 20× the paper's
//! drift): BIC took 8 segments on two of three seeds, where 16 raised the
//! score by 533 and 381 for 48 more parameters, and left an accelerometer
//! scale factor 4.1σ and 4.5σ off the truth, in one after a cascade of
//! encoder_scale and g_sensitivity. M_max is the largest power of 2
//! whose segments are at least [`MIN_SEGMENT_S`] long and at least
//! [`CORRELATION_SEGMENT`] noise correlation times (the integral time scale
//! of the fit's noise model), at most [`MAX_CHOSEN`]: shorter segments would
//! follow the motion's own time scales (knots every second or so) or the
//! correlated noise, not a drift.

use serde::Serialize;

use super::{score_all, DiagnoseError, Score};
use crate::calibrate::fit::Fit;
use crate::calibrate::CalibrateOptions;
use robimu_model::effects::CatalogueSetup;
use robimu_model::observations::Measurements;
use robimu_model::Robot;

/// Shortest segment of a chosen resolution, s: five trajectory knot spans
/// of the default excitation (1 s), so that a bias change cannot mimic a
/// motion-correlated error within a segment. Measured
/// (`host/cli/tests/drift.rs`): with 10 s (at most 16 segments in 300 s)
/// a 20× random walk left enough slow structure for g_sensitivity to be
/// added after it (score 29, 9 dof, p 6e-4); with 5 s (32) nothing was.
pub(crate) const MIN_SEGMENT_S: f64 = 5.0;

/// Shortest segment in noise correlation times.
pub(crate) const CORRELATION_SEGMENT: f64 = 100.0;

/// Finest resolution diagnose considers (6 parameters per segment).
pub(crate) const MAX_CHOSEN: usize = 32;

/// One resolution's score.
#[derive(Debug, Clone, Serialize)]
pub struct ResolutionScore {
    /// M.
    pub resolution: usize,
    /// Rao score statistic S_M at the fit before the effect was added.
    pub statistic: f64,
    /// Parameters k_M.
    pub dof: usize,
    /// AIC_M = −S_M + 2 k_M (smallest chosen).
    pub aic: f64,
}

/// The resolution chosen for an effect (its entry in `diagnosis.json`).
#[derive(Debug, Clone, Serialize)]
pub struct ResolutionChoice {
    /// The chosen M.
    pub chosen: usize,
    /// M_max from the session length and the noise correlation.
    pub max: usize,
    /// The spec that fits it again (`calibrate --effects bias_drift:M`).
    pub spec: String,
    /// Every M considered.
    pub candidates: Vec<ResolutionScore>,
}

/// M_max for a session over `span_s` seconds whose noise has the integral
/// correlation time `corr_s` (see the module doc).
pub(crate) fn max_resolution(span_s: f64, corr_s: f64) -> usize {
    let shortest = MIN_SEGMENT_S.max(CORRELATION_SEGMENT * corr_s);
    let mut m = 1;
    while 2 * m <= MAX_CHOSEN && span_s / (2 * m) as f64 >= shortest {
        m *= 2;
    }
    m
}

/// The integral time scale of the fit's noise, the largest over the
/// channels of every IMU: Δt · S(0)/(2σ²) (Δt/2 for white noise; Δt/(1 − φ) for AR(1)
/// with φ near 1).
fn correlation_time(data: &Measurements, at: &Fit) -> f64 {
    let t = &data.imu_t;
    let dt = if t.len() > 1 {
        (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64
    } else {
        0.0
    };
    crate::calibrate::noise_choice::fit_models(at)
        .flat_map(|m| m.imu.iter())
        .map(|c| 0.5 * dt * c.ar.low_frequency_ratio())
        .fold(0.0, f64::max)
}

/// When `best` is an effect with a resolution: score it at every M, set the
/// chosen one in `setup`, and return the choice with the score at it (which
/// replaces `best`). `None` (and `setup` unchanged) for other effects.
pub fn choose(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &mut CatalogueSetup,
    at: &Fit,
    best: &Score,
) -> Result<Option<(ResolutionChoice, Score)>, DiagnoseError> {
    if setup.resolution(&best.name).is_none() {
        return Ok(None);
    }
    let span = setup.span.t1 - setup.span.t0;
    let max = max_resolution(span, correlation_time(data, at));
    let mut candidates = Vec::new();
    let mut scores = Vec::new();
    let mut m = 1;
    while m <= max {
        let mut s = setup.clone();
        s.set_resolution(&best.name, m)?;
        let score =
            score_all(robot, data, opts, &s, at, std::slice::from_ref(&best.name))?.remove(0);
        candidates.push(ResolutionScore {
            resolution: m,
            statistic: score.statistic,
            dof: score.dof,
            aic: -score.statistic + 2.0 * score.dof as f64,
        });
        scores.push(score);
        m *= 2;
    }
    let k = (0..candidates.len())
        .min_by(|&a, &b| candidates[a].aic.total_cmp(&candidates[b].aic))
        .expect("M = 1 is always scored");
    let chosen = candidates[k].resolution;
    setup.set_resolution(&best.name, chosen)?;
    Ok(Some((
        ResolutionChoice {
            chosen,
            max,
            spec: setup.spec(&best.name),
            candidates,
        },
        scores.swap_remove(k),
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_finest_resolution_follows_the_session_and_the_noise() {
        // 300 s: 32 segments of 9.4 s (64 would be 4.7 s < 5 s)
        assert_eq!(max_resolution(300.0, 1.0 / 240.0), 32);
        assert_eq!(max_resolution(90.0, 1.0 / 240.0), 16);
        assert_eq!(max_resolution(9.0, 1.0 / 240.0), 1);
        // a 0.5 s noise correlation: segments of at least 50 s
        assert_eq!(max_resolution(300.0, 0.5), 4);
        // capped
        assert_eq!(max_resolution(86_400.0, 0.0), MAX_CHOSEN);
    }
}
