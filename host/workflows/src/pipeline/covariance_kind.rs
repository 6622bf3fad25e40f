//! The covariance a calibration reports when its verdict finds the model
//! inadequate (docs/model.md §8.5 `structure`, §4.6 *Sandwich of the
//! written fit*): the model's A⁻¹ widened to the sandwich A⁻¹BA⁻¹ of the
//! written fit, parameter by parameter.

use robimu_model::effects::CatalogueSetup;
use robimu_model::observations::Measurements;
use robimu_model::{ParamLayout, Robot};
use robimu_session::result::{CovarianceKindRecord, InflationRecord, VerdictRecord};

use crate::calibrate::fit::Fit;
use crate::calibrate::sandwich_fit::fit_sandwich;
use crate::calibrate::{CalibrateOptions, Calibration};
use crate::diagnose::effect_set;

/// The sandwich's score windows, s: about three periods of the motion's
/// band edge (1.3–1.5 Hz on the planned motions), long against the
/// misfit's correlation, short against the session (docs/model.md §4.6).
pub(super) const WINDOW_S: f64 = 2.0;

/// The Bartlett kernel's lags over the windows (none: the windows are
/// long against the misfit's correlation).
pub(super) const LAGS: usize = 0;

/// When `verdict`'s structure check failed: `cal`'s σ widened to the
/// sandwich of `fit` (its effects from `setup`, its noise model), each
/// parameter's σ by s_k = max(1, σ_sandwich/σ_k) and the covariance by
/// diag(s) Σ diag(s) (positive definite, A⁻¹'s correlations kept); the
/// record of it, said in the check's text. `None`, `cal` unchanged, when the check passed or the
/// sandwich cannot be formed (several IMUs).
pub(super) fn widen(
    (robot, data, opts): (&Robot, &Measurements, &CalibrateOptions),
    setup: &CatalogueSetup,
    fit: &Fit,
    verdict: &mut VerdictRecord,
    cal: &mut Calibration,
) -> Option<CovarianceKindRecord> {
    let check = verdict
        .checks
        .iter_mut()
        .find(|c| c.topic == "structure" && !c.ok)?;
    if cal.active != fit.active {
        return None;
    }
    let set = effect_set(setup, &fit.effects).ok()?;
    let sw = fit_sandwich(robot, data, opts, &set, fit, WINDOW_S, LAGS).ok()?;
    let layout = ParamLayout::new(robot);
    let factors: Vec<f64> = cal
        .active
        .iter()
        .map(|&k| match cal.sigma[k] > 0.0 {
            true => (sw.sigma[k] / cal.sigma[k]).max(1.0),
            false => 1.0,
        })
        .collect();
    let na = factors.len();
    for (i, si) in factors.iter().enumerate() {
        for (j, sj) in factors.iter().enumerate() {
            cal.covariance[i * na + j] *= si * sj;
        }
    }
    for (&k, s) in cal.active.iter().zip(&factors) {
        cal.sigma[k] *= s;
    }
    let reason = format!("structure: {}", check.text);
    let (c, s) = factors
        .iter()
        .enumerate()
        .fold((0, 1.0), |m, (c, &s)| if s > m.1 { (c, s) } else { m });
    check.text += &format!(
        "; the σ are widened to the sandwich of the fit (largest ×{s:.2}, {}; covariance_kind)",
        layout.specs()[cal.active[c]].name
    );
    Some(CovarianceKindRecord {
        kind: "sandwich".into(),
        reason,
        window_s: WINDOW_S,
        lags: LAGS,
        inflation: cal
            .active
            .iter()
            .zip(&factors)
            .map(|(&k, &factor)| InflationRecord {
                name: layout.specs()[k].name.clone(),
                factor,
            })
            .collect(),
    })
}
