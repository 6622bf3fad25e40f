//! The verdict on a calibration: can its result be trusted? One check per
//! line, then `trust: good / doubtful / bad` with the reasons:
//!
//! * **converged** — the solver's termination ([`robimu_solver::Termination::converged`]);
//!   not converged is *bad*;
//! * **residuals** — white or not (Ljung–Box, Bonferroni over the six
//!   channels, [`crate::noise_id::WHITENESS_ALPHA`]; the test `calibrate
//!   --noise-model auto` runs on the white fit, docs/model.md §4.6), with
//!   the noise model used; residuals that are not white and were not
//!   modelled (white kept), or a whitened RMS far from 1, are *doubtful*:
//!   something the model lacks (`robimu diagnose`) or wrong σ_z
//!   (`robimu noise`). Correlated noise the fit identified and modelled
//!   (GLS) passes, named; so do whitened residuals that still fail the
//!   test by a correlation that understates σ by at most
//!   [`WHITENED_TOLERANCE`] (noted). In a multi-IMU fit each IMU has its
//!   own noise model (docs/model.md §9): an IMU j ≥ 1 whose own residuals
//!   ask for another model than the one the fit used for it (a white or a
//!   given model that is not its noise) is *doubtful*, named (its σ are
//!   not those of its noise); IMUs whose noise merely differs are not;
//! * **undetermined** — parameters whose posterior σ is above
//!   [`UNDETERMINED`] of the prior σ: their estimate is the prior's, with
//!   the prior's σ — listed (the robot lengths apart: they need speed,
//!   paper §8.4), not a reason for doubt: the result says what it does not
//!   know (`robimu check` names them before the fit);
//! * **plausible** — estimates more than [`IMPLAUSIBLE`] prior σ from the
//!   prior mean (the gains' 1 ± 0.1, the IMU position's mount nominal
//!   ± 10 mm, τ's 0 ± 1 s, …: the priors are the plausible ranges, Table II),
//!   and g₀ against 9.81 ± [`G0_TOLERANCE`]: *doubtful*;
//! * **repeatability** (`calibrate --windows N`) — a window's estimate more
//!   than [`WINDOW_LIMIT`] of its σ from the full calibration: *doubtful*;
//! * **model** — the score test of every catalogue effect the written model
//!   lacks (Bonferroni over the candidates, docs/model.md §8.6): one that
//!   is significant (the model is rejected) is *doubtful*, named with why
//!   it is not in the model;
//! * **structure** — diagnose's tests for structure no effect explains, on
//!   the written model's whitened residuals ([`crate::diagnose::unexplained`]:
//!   a narrow spectral peak, a correlation with a regressor): structure
//!   that can move the parameters (a regressor followed, or a peak inside
//!   the motion's band, where the regressors carry their power) is
//!   *doubtful* — a discrepancy that follows the motion, which the score
//!   tests' catalogue does not describe, aliases into the parameters
//!   beyond their σ; a peak far above the motion's band (a sampling
//!   artefact) is noted.

use robimu_model::{ParamLayout, Robot};
use robimu_session::result::{EffectRecord, ModelTestsRecord, Trust, VerdictCheck, VerdictRecord};

use crate::calibrate::noise_choice::{settled, wanted, NoiseOutcome, Settle};
use crate::calibrate::Calibration;
use crate::diagnose::{unexplained, ResidualStats, UNEXPLAINED_ALPHA};
use crate::noise_id::{IdOptions, Identification, WHITENESS_ALPHA};
use crate::plan::information::robot_lengths;
use crate::repeatability::Repeatability;

/// σ / prior σ above which a parameter is undetermined.
pub(crate) const UNDETERMINED: f64 = 0.9;
/// Prior σ from the prior mean beyond which an estimate is implausible.
pub(crate) const IMPLAUSIBLE: f64 = 4.0;
/// Standard gravity and the tolerance of g₀ (m/s²).
pub(crate) const G0: f64 = 9.81;
/// See [`G0`].
pub(crate) const G0_TOLERANCE: f64 = 0.05;
/// Whitened residual RMS outside this range: the σ_z do not fit.
pub(crate) const RMS_RANGE: (f64, f64) = (0.67, 1.5);
/// |window − full| / σ_window beyond which the windows disagree.
pub(crate) const WINDOW_LIMIT: f64 = 4.0;

/// What the verdict looks at besides the calibration.
pub struct VerdictInput<'a> {
    /// The robot (its g₀ and parameter layout).
    pub robot: &'a Robot,
    /// The calibration.
    pub calibration: &'a Calibration,
    /// What the noise choice did (its `white_test` is the white fit's).
    pub noise: Option<&'a NoiseOutcome>,
    /// The identification from the final fit's raw residuals when the noise
    /// choice ran none (`--noise-model white` or a given model:
    /// [`crate::calibrate::noise_choice::residual_identification`]).
    pub whiteness: Option<&'a Identification>,
    /// The repeatability study, when asked for.
    pub repeatability: Option<&'a Repeatability>,
    /// A multi-IMU calibration's IMUs j ≥ 1: the identification from each
    /// one's raw residuals ([`crate::calibrate::noise_choice::other_imu_identifications`]).
    pub other_imus: &'a [(usize, Identification)],
    /// The tests of the model written against the catalogue's effects.
    pub model_tests: Option<&'a ModelTestsRecord>,
    /// The written model's residual statistics (IMU 0), for the
    /// structure the model leaves.
    pub residual_stats: Option<&'a ResidualStats>,
    /// The effects in the written model (None: the paper's model), for
    /// the next steps that name a model.
    pub effects: Option<&'a [EffectRecord]>,
}

/// The verdict (module doc).
pub fn verdict(input: &VerdictInput<'_>) -> VerdictRecord {
    let cal = input.calibration;
    let layout = cal.layout(input.robot);
    let mut checks = Vec::new();
    let mut bad = false;
    // converged
    let t = cal.summary.termination;
    bad |= !t.converged();
    checks.push(VerdictCheck {
        topic: "converged".into(),
        ok: t.converged(),
        text: format!("{t} after {} iterations", cal.summary.iterations.len()),
    });
    checks.push(residuals(input));
    checks.push(undetermined(&layout, cal));
    checks.push(plausible(input.robot, &layout, cal));
    if let Some(study) = input.repeatability {
        checks.push(repeatability(&layout, study));
    }
    if let Some(tests) = input.model_tests {
        checks.push(model(tests));
    }
    if let Some(stats) = input.residual_stats {
        checks.push(structure(stats));
    }
    record(checks, bad)
}

/// The verdict of `checks`: *bad* when `bad` (the fit did not converge),
/// else *good* when every check passed, else *doubtful*, with the failed
/// checks as the reasons.
pub(crate) fn record(checks: Vec<VerdictCheck>, bad: bool) -> VerdictRecord {
    let reasons: Vec<String> = checks
        .iter()
        .filter(|c| !c.ok)
        .map(|c| format!("{}: {}", c.topic, c.text))
        .collect();
    let trust = if bad {
        Trust::Bad
    } else if reasons.is_empty() {
        Trust::Good
    } else {
        Trust::Doubtful
    };
    VerdictRecord {
        trust,
        reasons,
        checks,
        next_steps: Vec::new(),
    }
}

fn p_values(id: &Identification) -> String {
    let names = robimu_session::IMU_COLUMNS;
    id.channels
        .iter()
        .zip(names)
        .zip(id.white)
        .filter(|(_, w)| !w)
        .map(|((c, n), _)| format!("{n} p = {:.1e}", c.ljung_box_p))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Factor of σ understatement the correlation left in the whitened
/// residuals may cause before the noise model counts as inadequate: 10 %.
pub(crate) const WHITENED_TOLERANCE: f64 = 1.1;

/// The channels whose identified AR model is at the largest order tried,
/// or whose whitened residuals still fail the whiteness test by a
/// correlation that understates σ by more than [`WHITENED_TOLERANCE`]:
/// correlation longer than a sensor's filter makes (docs/model.md §4.6).
/// The second: the channels that fail the test by less (a note).
fn beyond_ar(id: &Identification) -> (Option<String>, Option<String>) {
    let max = IdOptions::default().max_order;
    let alpha = WHITENESS_ALPHA / 6.0;
    let (mut bad, mut small) = (Vec::new(), Vec::new());
    for (c, n) in id.channels.iter().zip(robimu_session::IMU_COLUMNS) {
        let order = c.noise.ar.order();
        let p = c.ljung_box_whitened_p;
        let factor = c.whitened_understatement;
        if order >= max {
            bad.push(format!("{n}: AR({order}), the largest order tried"));
        } else if p < alpha && factor > WHITENED_TOLERANCE {
            bad.push(format!(
                "{n}: whitened p = {p:.1e}, σ understated ×{factor:.2}"
            ));
        } else if p < alpha {
            small.push(format!(
                "{n}: whitened p = {p:.1e}, σ understated ×{factor:.3}"
            ));
        }
    }
    let join = |v: Vec<String>| (!v.is_empty()).then(|| v.join(", "));
    (join(bad), join(small))
}

fn min_p(id: &Identification) -> f64 {
    id.channels
        .iter()
        .map(|c| c.ljung_box_p)
        .fold(f64::INFINITY, f64::min)
}

/// White or not, the model used, the whitened RMS.
fn residuals(input: &VerdictInput<'_>) -> VerdictCheck {
    let cal = input.calibration;
    let identified = input.noise.and_then(|n| n.identified.as_ref());
    let model = if cal.noise_model.is_white() {
        "white".to_string()
    } else {
        let p = cal.noise_model.max_order();
        let source = if identified.is_some() {
            "identified from the residuals"
        } else {
            "given"
        };
        format!("AR(≤{p}) {source}, generalised least squares")
    };
    let rms = cal.residual_rms;
    let off: Vec<String> = robimu_session::IMU_COLUMNS
        .iter()
        .zip(rms)
        .filter(|(_, r)| !(RMS_RANGE.0..=RMS_RANGE.1).contains(r))
        .map(|(n, r)| format!("{n} {r:.2}"))
        .collect();
    let rms_text = if off.is_empty() {
        String::new()
    } else {
        format!(
            "; whitened residual RMS {} (1 = as modelled): the σ_z do not fit the data (robimu noise)",
            off.join(", ")
        )
    };
    let test = input
        .noise
        .and_then(|n| n.white_test.as_ref())
        .or(input.whiteness);
    let warning = input.noise.and_then(|n| n.warning.as_ref());
    let (ok, text) = match (test, warning) {
        (_, Some(w)) => (false, format!("not white, not modelled ({w}); noise model {model}")),
        (Some(id), None) if id.white.iter().all(|&w| w) => (
            true,
            format!("white (Ljung-Box, smallest p = {:.2}); noise model {model}", min_p(id)),
        ),
        (Some(id), None) if !cal.noise_model.is_white() => {
            let used = identified.unwrap_or(id);
            match beyond_ar(used) {
                (None, small) => (
                    true,
                    format!(
                        "correlated ({}), modelled: noise model {model}{}",
                        p_values(id),
                        small.map_or(String::new(), |s| format!(
                            "; the whitened residuals keep a small correlation ({s}, within ×{WHITENED_TOLERANCE})"
                        ))
                    ),
                ),
                (Some(why), _) => (
                    false,
                    format!(
                        "correlated beyond what the AR noise model captures ({why}): a slow discrepancy — bias drift or an effect the model lacks? (robimu diagnose); noise model {model}"
                    ),
                ),
            }
        }
        (Some(id), None) => (
            false,
            format!(
                "not white ({}) and no AR order or motion level explains it: an effect the model lacks? (robimu diagnose); noise model {model}",
                p_values(id)
            ),
        ),
        (None, None) => (true, format!("not tested; noise model {model}")),
    };
    let others = other_imus(input);
    VerdictCheck {
        topic: "residuals".into(),
        ok: ok && off.is_empty() && others.is_empty(),
        text: text + &rms_text + &others,
    }
}

/// The IMUs j ≥ 1 whose residuals ask for another noise model than the one
/// the fit used for that IMU (docs/model.md §9: each IMU its own):
/// correlated under a white model, or white or differently correlated
/// under an AR one (orders, φ within 0.1, σ within 20 %): their σ are not
/// those of their noise.
fn other_imus(input: &VerdictInput<'_>) -> String {
    let cal = input.calibration;
    let model_of = |j: usize| {
        cal.extra_noise_models
            .get(j.wrapping_sub(1))
            .unwrap_or(&cal.noise_model)
    };
    let loose = Settle {
        max_refits: 0,
        phi: 0.1,
        sigma: 0.2,
    };
    let off: Vec<String> = input
        .other_imus
        .iter()
        .filter_map(|(j, id)| {
            let model = model_of(*j);
            let differs = match wanted(id) {
                None => !model.is_white(),
                Some(m) => model.is_white() || !settled(&m, model, &loose),
            };
            differs.then(|| format!("IMU {j} ({})", p_values(id)))
        })
        .collect();
    if off.is_empty() {
        return String::new();
    }
    format!(
        "; the residuals of {} ask for another noise model than the one the fit used for it: their σ are not those of their noise (--noise-model auto identifies each IMU's own)",
        off.join(", ")
    )
}

/// The written model against the catalogue: an effect it lacks that the
/// score test finds significant rejects it.
fn model(t: &ModelTestsRecord) -> VerdictCheck {
    let level = t.alpha / t.candidates.max(1) as f64;
    let text = if t.significant.is_empty() {
        let largest = t.largest_remaining.as_ref().map_or(String::new(), |s| {
            format!("; largest {} p = {:.2e}", s.name, s.p_value)
        });
        format!(
            "no catalogue effect is missing (score tests of {} candidates, p ≥ {level:.1e} each{largest})",
            t.candidates
        )
    } else {
        // the candidates grouped by why the model lacks them, in order
        let mut groups: Vec<(&str, Vec<String>)> = Vec::new();
        for s in &t.significant {
            let item = format!("{} (p = {:.1e})", s.name, s.p_value);
            match groups.iter_mut().find(|(r, _)| *r == s.reason) {
                Some((_, v)) => v.push(item),
                None => groups.push((&s.reason, vec![item])),
            }
        }
        let missing: Vec<String> = groups
            .iter()
            .map(|(reason, items)| format!("{}: {reason}", items.join(", ")))
            .collect();
        format!(
            "the data reject the model (score p < {level:.1e}): {}",
            missing.join("; ")
        )
    };
    VerdictCheck {
        topic: "model".into(),
        ok: t.significant.is_empty(),
        text,
    }
}

/// The structure the written model leaves in its residuals (module doc).
fn structure(stats: &ResidualStats) -> VerdictCheck {
    let found = unexplained(stats);
    let band = stats
        .motion_band_hz
        .map_or("the motion's band unknown".to_string(), |b| {
            format!("the motion's band below {b:.2} Hz")
        });
    let (moving, harmless): (Vec<_>, Vec<_>) = found.iter().partition(|u| u.affects_parameters());
    let level = UNEXPLAINED_ALPHA / 6.0;
    let (ok, text) = if moving.is_empty() {
        let note = if harmless.is_empty() {
            String::new()
        } else {
            let items: Vec<String> = harmless.iter().map(|u| u.describe(false)).collect();
            format!(
                "; above the motion's band, where no parameter's regressor has power: {}",
                items.join("; ")
            )
        };
        (
            true,
            format!("no structure left that follows the motion (narrow peaks and regressor correlations, p ≥ {level:.1e} each; {band}){note}"),
        )
    } else {
        let items: Vec<String> = moving.iter().map(|u| u.describe(false)).collect();
        (
            false,
            format!(
                "the residuals keep structure that follows the motion and no effect of the model explains ({}; {band}): it moves the parameters beyond their σ (robimu diagnose)",
                items.join("; ")
            ),
        )
    };
    VerdictCheck {
        topic: "structure".into(),
        ok,
        text,
    }
}

/// Parameters whose σ stayed at the prior's.
fn undetermined(layout: &ParamLayout, cal: &Calibration) -> VerdictCheck {
    let lengths = robot_lengths(layout);
    let specs = layout.specs();
    let (mut len, mut other) = (Vec::new(), Vec::new());
    for &k in &cal.active {
        if cal.sigma[k] > UNDETERMINED * specs[k].sigma {
            let name = specs[k].name.clone();
            if lengths.contains(&k) {
                len.push(name);
            } else {
                other.push(name);
            }
        }
    }
    let mut text = if other.is_empty() {
        "none beyond the robot lengths".to_string()
    } else {
        format!(
            "{} (σ > {UNDETERMINED} prior σ: the estimates are the prior's)",
            other.join(", ")
        )
    };
    if !len.is_empty() {
        text.push_str(&format!(
            "; {} robot length(s) at the prior ({}): expected below high speeds",
            len.len(),
            len.join(", ")
        ));
    }
    VerdictCheck {
        topic: "undetermined".into(),
        ok: true,
        text,
    }
}

/// Estimates far outside their prior, and g₀.
fn plausible(robot: &Robot, layout: &ParamLayout, cal: &Calibration) -> VerdictCheck {
    let specs = layout.specs();
    let mut far = Vec::new();
    for &k in &cal.active {
        let s = &specs[k];
        let z = (cal.x[k] - s.nominal) / s.sigma;
        if z.abs() > IMPLAUSIBLE {
            let unit = robimu_model::units::DisplayUnit::for_si(s.unit);
            far.push(format!(
                "{} = {:.4} {} (prior {:.4} ± {:.4}, {z:+.1} σ)",
                s.name,
                unit.show(cal.x[k]),
                unit.symbol(),
                unit.show(s.nominal),
                unit.show(s.sigma)
            ));
        }
    }
    let g0 = robot.gravity();
    let g_ok = (g0 - G0).abs() <= G0_TOLERANCE;
    let mut text = if far.is_empty() {
        format!("every estimate within {IMPLAUSIBLE} prior σ of its prior mean")
    } else {
        far.join("; ")
    };
    text.push_str(&format!(
        "; g0 = {g0:.3} m/s²{}",
        if g_ok {
            ""
        } else {
            " (not 9.81 ± 0.05: check session.toml `gravity`)"
        }
    ));
    VerdictCheck {
        topic: "plausible".into(),
        ok: far.is_empty() && g_ok,
        text,
    }
}

/// The windows against the full calibration.
fn repeatability(layout: &ParamLayout, study: &Repeatability) -> VerdictCheck {
    let worst = study
        .parameters
        .iter()
        .max_by(|a, b| a.relative_to_window.total_cmp(&b.relative_to_window));
    let Some(w) = worst else {
        return VerdictCheck {
            topic: "repeatability".into(),
            ok: true,
            text: "no windows".into(),
        };
    };
    let name = &layout.specs()[w.index].name;
    let ok = w.relative_to_window <= WINDOW_LIMIT;
    VerdictCheck {
        topic: "repeatability".into(),
        ok,
        text: format!(
            "{} windows: largest difference from the full calibration {name} in window {}, {:.1} × its σ (limit {WINDOW_LIMIT})",
            study.windows.len(),
            w.window + 1,
            w.relative_to_window
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_model::PerChannel;

    /// Residual statistics of 45 000 samples whose gz channel has a narrow
    /// peak (p = 1e-30) at `peak_hz`, the motion's band ending at 1.46 Hz,
    /// and whose gy follows a regressor with `z`.
    fn stats(peak_hz: f64, z: f64) -> ResidualStats {
        let mut s = ResidualStats {
            samples: 45_000,
            regressors: 40,
            motion_band_hz: Some(1.46),
            ..ResidualStats::default()
        };
        s.spectral_peak = PerChannel(std::array::from_fn(|c| {
            Some((peak_hz, if c == 5 { 2.3 } else { 1.1 }))
        }));
        s.spectral_peak_p = PerChannel(std::array::from_fn(|c| {
            Some(if c == 5 { 1e-30 } else { 0.5 })
        }));
        s.top_regressor = PerChannel(std::array::from_fn(|c| {
            let z = if c == 4 { z } else { 1.0 };
            ("q1".to_string(), z / 45_000f64.sqrt(), z)
        }));
        s
    }

    /// A peak inside the motion's band, or a regressor followed (|z| = 5:
    /// p = 40·5.7e-7 = 2.3e-5 < 0.01/6), makes the check fail; the same
    /// peak at 5 Hz, above the band, is noted and passes; |z| = 3 (p = 0.11)
    /// is no correlation.
    #[test]
    fn structure_inside_the_motions_band_or_along_a_regressor_is_doubtful() {
        let inside = structure(&stats(0.88, 3.0));
        assert!(!inside.ok, "{}", inside.text);
        assert!(
            inside.text.contains("gz a narrow peak at 0.88 Hz"),
            "{}",
            inside.text
        );
        let above = structure(&stats(4.98, 3.0));
        assert!(above.ok, "{}", above.text);
        assert!(
            above.text.contains("above the motion's band") && above.text.contains("4.98 Hz"),
            "{}",
            above.text
        );
        let follows = structure(&stats(4.98, 5.0));
        assert!(!follows.ok, "{}", follows.text);
        assert!(
            follows.text.contains("gy") && follows.text.contains("follows q1"),
            "{}",
            follows.text
        );
        // no band known: a peak cannot be placed, so it does not count
        let mut unknown = stats(0.88, 3.0);
        unknown.motion_band_hz = None;
        assert!(structure(&unknown).ok);
    }
}
