//! The diagnosis of a pose session (docs/model.md §7.9, *diagnosis*): the
//! catalogue's IMU-side effects, score-tested against the pose
//! calibration's MAP fit.
//!
//! * **Candidates**: the effects whose columns C_e(i) need only the IMU's
//!   own quantities ([`Effect::imu_columns`]: g_sensitivity, size_effect,
//!   clock_drift, sensor_delay, bias_drift; temperature_bias where the
//!   session has a temperature, which a pose session's files do not
//!   carry). The joint-side ones (joint_elasticity, encoder_scale,
//!   resonance) act through joint angles and links that a pose session
//!   does not have. bias_drift at its default resolution (one segment: a
//!   linear drift).
//! * **Tests**: one pass over the IMU samples with every candidate's
//!   columns ([`robimu_solver::PoseProblem::extra_sums`]) gives their
//!   efficient information V and score u ([`Information`]); a set E's
//!   statistic is S(E) = u_Eᵀ V_E⁻¹ u_E.
//! * **Search**: the joint path's false-alarm control (Bonferroni α/K over
//!   the K candidates offered) and rules, on conditional scores instead of
//!   refits: in each round a candidate b is scored given the effects E
//!   found so far, S(b | E) = S(E ∪ b) − S(E) ~ χ²_{k_b} (the score test
//!   of b in the model with E, to first order the score after refitting
//!   E); the best one below α/K is added unless its parameters are not
//!   determined apart from E (ρ²_max > [`MAX_ALIASING`], the joint path's
//!   [`crate::diagnose::determination`] rule), with the other significant
//!   candidates compared to it ([`Alternative`], the ambiguity rule).
//! * **Not done**: the refit with θ_e appended to x. The effects' values
//!   given are the one-step (Gauss–Newton) estimates −V_E⁻¹ u_E from the
//!   baseline fit with their σ, and the LR statistic, ΔBIC and residuals
//!   after are not computed (`null` in diagnosis.json).

use faer::Mat;
use robimu_model::effects::{self, CatalogueSetup, Effect, MassModel, SessionSpan};
use robimu_model::pose_measurement::inertial::PoseImuSample;
use robimu_model::pose_measurement::G0;
use robimu_model::PoseMeasurements;
use serde::Serialize;

use super::score::Information;
use super::{fit_poses, PoseCalibration, PoseCalibrationError, PoseCalibrationOptions, PoseFit};
use crate::diagnose::ranking::{aliasing, compare};
use crate::diagnose::{AddedParameter, AliasedWith, FoundEffect, Rejected, Score, MAX_ALIASING};

/// Settings of [`diagnose_poses`].
#[derive(Debug, Clone)]
pub struct PoseDiagnoseOptions {
    /// Family-wise significance level α (Bonferroni over the candidates).
    pub alpha: f64,
    /// Candidates (empty: every IMU-side effect of the catalogue).
    pub candidates: Vec<String>,
}

impl Default for PoseDiagnoseOptions {
    fn default() -> Self {
        Self {
            alpha: 0.01,
            candidates: Vec::new(),
        }
    }
}

/// A catalogue effect that is not a candidate of a pose session, and why.
#[derive(Debug, Clone, Serialize)]
pub struct NotApplicable {
    /// Effect name.
    pub name: String,
    /// Why.
    pub reason: String,
}

/// The outcome of [`diagnose_poses`].
#[derive(Debug, Clone)]
pub struct PoseDiagnosis {
    /// The baseline: the pose calibration.
    pub calibration: PoseCalibration,
    /// Effects in the order they were chosen.
    pub found: Vec<FoundEffect>,
    /// Significant candidates not chosen (not determined apart from those found).
    pub rejected: Vec<Rejected>,
    /// The scores of the last round (none significant), best first.
    pub last_scores: Vec<Score>,
    /// Bonferroni threshold α/K.
    pub threshold: f64,
    /// K, the candidates offered.
    pub candidates: usize,
    /// The catalogue's effects that do not apply.
    pub not_applicable: Vec<NotApplicable>,
    /// IMU noise σ_z of the tests.
    pub sigma_z: [f64; 6],
}

/// Why a catalogue effect is no candidate of a pose session (`None`: it is one).
fn not_applicable(name: &str) -> Option<&'static str> {
    match name {
        "joint_elasticity" | "encoder_scale" | "resonance" => Some(
            "acts through the joint angles or links; a pose session has none (docs/model.md §7.9)",
        ),
        "temperature_bias" => Some("needs an IMU temperature, which a pose session does not carry"),
        _ => None,
    }
}

/// A candidate: its name, parameters and place among the stacked columns.
struct Candidate {
    effect: Box<dyn Effect>,
    range: std::ops::Range<usize>,
}

impl Candidate {
    fn name(&self) -> &'static str {
        self.effect.name()
    }
}

/// The candidates offered from `requested` (empty: all applicable).
fn offered(
    setup: &CatalogueSetup,
    requested: &[String],
) -> Result<(Vec<Candidate>, Vec<NotApplicable>), PoseCalibrationError> {
    let bad = |m: String| PoseCalibrationError::Input(m);
    for r in requested {
        if !effects::NAMES.contains(&r.as_str()) {
            return Err(bad(effects::UnknownEffect(r.clone()).to_string()));
        }
        if let Some(why) = not_applicable(r) {
            return Err(bad(format!(
                "effect `{r}` does not apply to a pose session: it {why}"
            )));
        }
    }
    let mut out = Vec::new();
    let mut skipped = Vec::new();
    let mut at = 0;
    for name in effects::NAMES {
        if let Some(why) = not_applicable(name) {
            skipped.push(NotApplicable {
                name: name.into(),
                reason: why.into(),
            });
            continue;
        }
        if !requested.is_empty() && !requested.iter().any(|r| r == name) {
            continue;
        }
        let effect = effects::by_name(setup, name).map_err(|e| bad(e.to_string()))?;
        let k = effect.params().len();
        out.push(Candidate {
            effect,
            range: at..at + k,
        });
        at += k;
    }
    Ok((out, skipped))
}

/// Diagnose a pose session (module doc): calibrate, then score the
/// IMU-side effects; `stage` sees each stage's message.
pub fn diagnose_poses(
    data: &PoseMeasurements,
    opts: &PoseCalibrationOptions,
    dopts: &PoseDiagnoseOptions,
    mut stage: impl FnMut(&str),
) -> Result<PoseDiagnosis, PoseCalibrationError> {
    if !(dopts.alpha > 0.0 && dopts.alpha < 1.0) {
        return Err(PoseCalibrationError::Input(format!(
            "alpha must be in (0, 1) (got {})",
            dopts.alpha
        )));
    }
    let (t0, t1) = match (data.imu_t.first(), data.imu_t.last()) {
        (Some(&a), Some(&b)) => (a, b),
        _ => return Err(PoseCalibrationError::Input("no IMU samples".into())),
    };
    let setup = CatalogueSetup::new(SessionSpan { t0, t1 }, MassModel::none(), G0, None);
    let (cands, skipped) = offered(&setup, &dopts.candidates)?;
    let (calibration, fit) = fit_poses(data, opts, &mut stage, |_| {})?;
    stage(&format!(
        "scoring {} IMU-side effects of the catalogue",
        cands.len()
    ));
    let info = information(&fit, &cands)?;
    let threshold = dopts.alpha / cands.len().max(1) as f64;
    let search = search(&info, &cands, threshold);
    let rms_before: [f64; 6] = std::array::from_fn(|c| calibration.imu_rms[c] / opts.sigma_z[c]);
    let found = search
        .found
        .into_iter()
        .map(|f| found_record(f, &cands, rms_before))
        .collect();
    Ok(PoseDiagnosis {
        calibration,
        found,
        rejected: search.rejected,
        last_scores: search.last_scores,
        threshold,
        candidates: cands.len(),
        not_applicable: skipped,
        sigma_z: opts.sigma_z,
    })
}

/// Every candidate's columns stacked, their V and u at the fit.
fn information(fit: &PoseFit, cands: &[Candidate]) -> Result<Information, PoseCalibrationError> {
    let k = cands.last().map_or(0, |c| c.range.end);
    let sums = fit
        .problem
        .extra_sums(&fit.theta, k, |_, sample: &PoseImuSample<'_>, cols| {
            for c in cands {
                c.effect.imu_columns(sample, &mut cols[c.range.clone()]);
            }
        })?;
    let prior: Vec<f64> = cands
        .iter()
        .flat_map(|c| c.effect.params())
        .map(|p| p.prior_sigma.powi(-2))
        .collect();
    Ok(Information::new(&sums, &prior, &fit.factor))
}

/// One effect chosen by [`search`].
struct Chosen {
    /// Index into the candidates.
    cand: usize,
    score: Score,
    /// The round's scores, best first.
    scores: Vec<Score>,
    alternatives: Vec<crate::diagnose::Alternative>,
    /// ρ²_max against the effects before it.
    aliasing: f64,
    /// One-step estimates and σ of its parameters with those before it.
    step: Vec<(f64, f64)>,
}

/// What the search ends with.
struct Search {
    found: Vec<Chosen>,
    rejected: Vec<Rejected>,
    last_scores: Vec<Score>,
}

/// The indices of the candidates `set` in the stacked columns.
fn columns_of(cands: &[Candidate], set: &[usize]) -> Vec<usize> {
    set.iter().flat_map(|&c| cands[c].range.clone()).collect()
}

/// S of the candidates `set` (0 for none; NaN when V is singular).
fn statistic(info: &Information, cands: &[Candidate], set: &[usize]) -> f64 {
    if set.is_empty() {
        return 0.0;
    }
    info.test(&columns_of(cands, set))
        .map_or(f64::NAN, |t| t.statistic)
}

/// The forward search of the module doc.
fn search(info: &Information, cands: &[Candidate], threshold: f64) -> Search {
    let mut s = Search {
        found: Vec::new(),
        rejected: Vec::new(),
        last_scores: Vec::new(),
    };
    let mut chosen: Vec<usize> = Vec::new();
    loop {
        let base = statistic(info, cands, &chosen);
        let mut scores: Vec<(usize, Score)> = (0..cands.len())
            .filter(|c| {
                !chosen.contains(c) && !s.rejected.iter().any(|r| r.name == cands[*c].name())
            })
            .map(|c| {
                let with: Vec<usize> = chosen.iter().copied().chain([c]).collect();
                let stat = (statistic(info, cands, &with) - base).max(0.0);
                let dof = cands[c].range.len();
                let p_value = if stat.is_finite() {
                    crate::stats::chi2_sf(stat, dof as f64)
                } else {
                    1.0
                };
                (
                    c,
                    Score {
                        name: cands[c].name().into(),
                        statistic: stat,
                        dof,
                        p_value,
                    },
                )
            })
            .collect();
        scores.sort_by(|a, b| {
            (a.1.p_value)
                .total_cmp(&b.1.p_value)
                .then(b.1.statistic.total_cmp(&a.1.statistic))
        });
        let plain: Vec<Score> = scores.iter().map(|(_, s)| s.clone()).collect();
        let Some((best, score)) = scores.first().cloned() else {
            return s;
        };
        if !(score.p_value < threshold) {
            s.last_scores = plain;
            return s;
        }
        let with: Vec<usize> = chosen.iter().copied().chain([best]).collect();
        let rho2 = determination(info, cands, &chosen, best);
        if rho2.0 > MAX_ALIASING {
            s.rejected.push(Rejected {
                name: score.name.clone(),
                statistic: score.statistic,
                dof: score.dof,
                p_value: score.p_value,
                lr_statistic: f64::NAN,
                aliasing: rho2.0,
                aliased_with: rho2.1,
                reason: format!(
                    "not determined apart from the effects found (ρ²_max {:.3} > {MAX_ALIASING})",
                    rho2.0
                ),
            });
            continue;
        }
        let alternatives = scores[1..]
            .iter()
            .filter(|(_, b)| b.p_value < threshold)
            .map(|(c, b)| {
                let both: Vec<usize> = with.iter().copied().chain([*c]).collect();
                let joint = (statistic(info, cands, &both) - base).max(0.0);
                compare(&score, b, joint, threshold)
            })
            .collect();
        let step = info
            .test(&columns_of(cands, &with))
            .map(|t| {
                let n = t.step.len() - score.dof;
                (n..t.step.len())
                    .map(|i| (t.step[i], t.step_sigma[i]))
                    .collect()
            })
            .unwrap_or_default();
        chosen.push(best);
        s.found.push(Chosen {
            cand: best,
            score,
            scores: plain,
            alternatives,
            aliasing: rho2.0,
            step,
        });
    }
}

/// ρ²_max of candidate `b`'s parameters against the effects `known`, and
/// the single one it is most aliased with (the joint path's rule, on V).
fn determination(
    info: &Information,
    cands: &[Candidate],
    known: &[usize],
    b: usize,
) -> (f64, Option<AliasedWith>) {
    if known.is_empty() {
        return (0.0, None);
    }
    let idx = columns_of(cands, &known.iter().copied().chain([b]).collect::<Vec<_>>());
    let v = Mat::from_fn(idx.len(), idx.len(), |i, j| info.v[(idx[i], idx[j])]);
    let Some(cov) = inverse(&v) else {
        return (1.0, None);
    };
    let nb = cands[b].range.len();
    let b_range = idx.len() - nb..idx.len();
    let mut ranges = Vec::new();
    let mut at = 0;
    for &c in known {
        let k = cands[c].range.len();
        ranges.push((c, at..at + k));
        at += k;
    }
    let all: Vec<_> = ranges.iter().map(|(_, r)| r.clone()).collect();
    let total = aliasing(&v, &cov, &all, &b_range).unwrap_or(1.0);
    let most = ranges
        .iter()
        .map(|(c, r)| AliasedWith {
            name: cands[*c].name().into(),
            rho2: aliasing(&v, &cov, std::slice::from_ref(r), &b_range).unwrap_or(1.0),
        })
        .max_by(|a, b| a.rho2.total_cmp(&b.rho2));
    (total, most)
}

fn inverse(m: &Mat<f64>) -> Option<Mat<f64>> {
    use faer::linalg::solvers::DenseSolveCore;
    m.llt(faer::Side::Lower).ok().map(|l| l.inverse())
}

/// The joint path's record of an effect found; what only a refit gives
/// (LR, ΔBIC, residuals after, baseline moves) is NaN (`null`).
fn found_record(f: Chosen, cands: &[Candidate], rms_before: [f64; 6]) -> FoundEffect {
    let params = cands[f.cand].effect.params();
    let ambiguous_with = f
        .alternatives
        .iter()
        .filter(|a| a.ambiguous)
        .map(|a| a.name.clone())
        .collect();
    FoundEffect {
        name: f.score.name.clone(),
        imu: Some(0),
        statistic: f.score.statistic,
        dof: f.score.dof,
        p_value: f.score.p_value,
        lr_statistic: f64::NAN,
        lr_p_value: f64::NAN,
        delta_bic: f64::NAN,
        rms_before,
        rms_after: [f64::NAN; 6],
        parameters: params
            .iter()
            .zip(&f.step)
            .map(|(p, &(value, sigma))| AddedParameter {
                name: p.name.clone(),
                unit: p.unit.into(),
                value,
                sigma,
            })
            .collect(),
        baseline_moves: Vec::new(),
        scores: f.scores,
        resolution: None,
        alternatives: f.alternatives,
        ambiguous_with,
        aliasing: f.aliasing,
    }
}

#[cfg(test)]
#[path = "diagnose_tests.rs"]
mod tests;
