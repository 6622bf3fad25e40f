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
//! * **Search**: the joint path's (docs/model.md §4.9), on the same
//!   rules: in each round every candidate b is scored given the effects E
//!   found so far, S(b | E) = S(E ∪ b) − S(E) ~ χ²_{k_b} at the fit with
//!   E; the best one below the Bonferroni threshold α/K (K candidates
//!   offered) is rejected if its parameters are not determined apart from
//!   E (ρ²_max > [`MAX_ALIASING`], [`crate::diagnose::determination`]'s
//!   rule on V), else refitted ([`super::refit`]: θ_E appended to x) and
//!   added when the refit's likelihood ratio confirms it (p < α/K), else
//!   the search ends. The other candidates significant in the round are
//!   compared with it ([`Alternative`](crate::diagnose::Alternative), the
//!   ambiguity rule).

use faer::Mat;
use robimu_model::effects::{self, CatalogueSetup, Effect, MassModel, SessionSpan};
use robimu_model::pose_measurement::inertial::PoseImuSample;
use robimu_model::pose_measurement::G0;
use robimu_model::PoseMeasurements;
use serde::Serialize;

use super::refit::{EffectFit, Stacked};
use super::score::Information;
use super::{PoseCalibration, PoseCalibrationError, PoseCalibrationOptions};
use crate::diagnose::ranking::{aliasing, compare};
use crate::diagnose::{
    AddedParameter, AliasedWith, FoundEffect, ParameterMove, Rejected, Score, MAX_ALIASING,
};

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
    /// The calibration of the final model (with the effects found, their
    /// terms taken out of the IMU samples); `None` when none was found.
    pub final_calibration: Option<PoseCalibration>,
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
    let columns = |sample: &PoseImuSample<'_>, cols: &mut [[f64; 6]]| {
        for c in &cands {
            c.effect.imu_columns(sample, &mut cols[c.range.clone()]);
        }
    };
    let stacked = Stacked {
        columns: &columns,
        prior: (cands.iter().flat_map(|c| c.effect.params()))
            .map(|p| p.prior_sigma.powi(-2))
            .collect(),
    };
    stage("calibrating the pose session (the baseline)");
    let baseline = stacked.fit(data, opts, vec![0.0; stacked.len()], None)?;
    let threshold = dopts.alpha / cands.len().max(1) as f64;
    let problem = Problem {
        data,
        opts,
        cands: &cands,
        stacked: &stacked,
        threshold,
    };
    stage(&format!(
        "scoring {} IMU-side effects of the catalogue",
        cands.len()
    ));
    let search = search(&problem, &baseline, &mut stage)?;
    Ok(PoseDiagnosis {
        calibration: baseline.cal,
        final_calibration: search.fit.map(|f| f.cal),
        found: search.found,
        rejected: search.rejected,
        last_scores: search.last_scores,
        threshold,
        candidates: cands.len(),
        not_applicable: skipped,
        sigma_z: opts.sigma_z,
    })
}

/// What a search runs on.
struct Problem<'a> {
    data: &'a PoseMeasurements,
    opts: &'a PoseCalibrationOptions,
    cands: &'a [Candidate],
    stacked: &'a Stacked<'a>,
    threshold: f64,
}

/// What the search ends with.
struct Search {
    /// The final fit (`None`: the baseline).
    fit: Option<EffectFit>,
    found: Vec<FoundEffect>,
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

/// Every candidate not in `chosen` nor rejected scored given `chosen` at
/// `info`, best first.
fn round_scores(
    info: &Information,
    cands: &[Candidate],
    chosen: &[usize],
    rejected: &[Rejected],
) -> Vec<(usize, Score)> {
    let base = statistic(info, cands, chosen);
    let mut scores: Vec<(usize, Score)> = (0..cands.len())
        .filter(|c| !chosen.contains(c) && !rejected.iter().any(|r| r.name == cands[*c].name()))
        .map(|c| {
            let with: Vec<usize> = chosen.iter().copied().chain([c]).collect();
            let stat = (statistic(info, cands, &with) - base).max(0.0);
            let dof = cands[c].range.len();
            let p_value = if stat.is_finite() {
                crate::stats::chi2_sf(stat, dof as f64)
            } else {
                1.0
            };
            let name = cands[c].name().into();
            (
                c,
                Score {
                    name,
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
    scores
}

/// The forward search of the module doc from the fit `baseline`.
fn search(
    p: &Problem<'_>,
    baseline: &EffectFit,
    stage: &mut impl FnMut(&str),
) -> Result<Search, PoseCalibrationError> {
    let cands = p.cands;
    let mut s = Search {
        fit: None,
        found: Vec::new(),
        rejected: Vec::new(),
        last_scores: Vec::new(),
    };
    let mut chosen: Vec<usize> = Vec::new();
    loop {
        let cur = s.fit.as_ref().unwrap_or(baseline);
        let scores = round_scores(&cur.info, cands, &chosen, &s.rejected);
        let plain: Vec<Score> = scores.iter().map(|(_, s)| s.clone()).collect();
        let Some((best, score)) = scores.first().cloned() else {
            return Ok(s);
        };
        if score.p_value.is_nan() || score.p_value >= p.threshold {
            s.last_scores = plain;
            return Ok(s);
        }
        let (rho2, most) = determination(&cur.info, cands, &chosen, best);
        if rho2 > MAX_ALIASING {
            s.rejected.push(Rejected {
                name: score.name.clone(),
                statistic: score.statistic,
                dof: score.dof,
                p_value: score.p_value,
                lr_statistic: f64::NAN,
                aliasing: rho2,
                aliased_with: most,
                reason: format!(
                    "not determined apart from the effects found (ρ²_max {rho2:.3} > {MAX_ALIASING})"
                ),
            });
            continue;
        }
        let with: Vec<usize> = chosen.iter().copied().chain([best]).collect();
        stage(&format!("refitting with {}", score.name));
        let next = p
            .stacked
            .refit(p.data, p.opts, &columns_of(cands, &with), cur)?;
        let lr = 2.0 * (cur.cost - next.cost);
        let lr_p = crate::stats::chi2_sf(lr.max(0.0), score.dof as f64);
        if lr_p >= p.threshold {
            s.last_scores = plain;
            return Ok(s);
        }
        let base = statistic(&cur.info, cands, &chosen);
        let alternatives = scores[1..]
            .iter()
            .filter(|(_, b)| b.p_value < p.threshold)
            .map(|(c, b)| {
                let both: Vec<usize> = with.iter().copied().chain([*c]).collect();
                let joint = (statistic(&cur.info, cands, &both) - base).max(0.0);
                compare(&score, b, joint, p.threshold)
            })
            .collect();
        let found = Chosen {
            cand: best,
            score,
            scores: plain,
            alternatives,
            aliasing: rho2,
            lr,
            lr_p,
        };
        s.found.push(found_record(found, p, cur, &next));
        chosen.push(best);
        s.fit = Some(next);
    }
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
    /// The refit's likelihood ratio and its p-value.
    lr: f64,
    lr_p: f64,
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

/// The joint path's record of an effect found at the fit `before`,
/// refitted into `after`.
fn found_record(f: Chosen, p: &Problem<'_>, before: &EffectFit, after: &EffectFit) -> FoundEffect {
    let cand = &p.cands[f.cand];
    // σ of θ_e with every other unknown (θ_E included) estimated
    let all: Vec<usize> = (0..p.cands.len())
        .filter(|c| {
            after.theta_e[p.cands[*c].range.clone()]
                .iter()
                .any(|v| *v != 0.0)
        })
        .flat_map(|c| p.cands[c].range.clone())
        .collect();
    let sig: Vec<f64> = match inverse(&Mat::from_fn(all.len(), all.len(), |i, j| {
        after.info.v[(all[i], all[j])]
    })) {
        Some(cov) => cand
            .range
            .clone()
            .map(|c| {
                all.iter()
                    .position(|&a| a == c)
                    .map_or(f64::NAN, |i| cov[(i, i)].max(0.0).sqrt())
            })
            .collect(),
        None => vec![f64::NAN; cand.range.len()],
    };
    let rms = |e: &EffectFit| -> [f64; 6] {
        std::array::from_fn(|c| e.cal.imu_rms[c] / p.opts.sigma_z[c])
    };
    let n_res = 6.0 * before.cal.imu_used as f64;
    let (b, a) = (&before.cal, &after.cal);
    let baseline_moves = (0..b.x.len())
        .filter(|&k| (a.x[k] - b.x[k]).abs() > a.sigma[k])
        .map(|k| ParameterMove {
            name: a.names[k].clone(),
            before: b.x[k],
            after: a.x[k],
            sigma: a.sigma[k],
        })
        .collect();
    FoundEffect {
        name: f.score.name.clone(),
        imu: Some(0),
        statistic: f.score.statistic,
        dof: f.score.dof,
        p_value: f.score.p_value,
        lr_statistic: f.lr,
        lr_p_value: f.lr_p,
        delta_bic: -f.lr + f.score.dof as f64 * n_res.ln(),
        rms_before: rms(before),
        rms_after: rms(after),
        parameters: (cand.effect.params().iter().zip(cand.range.clone()).zip(sig))
            .map(|((par, c), sigma)| AddedParameter {
                name: par.name.clone(),
                unit: par.unit.into(),
                value: after.theta_e[c],
                sigma,
            })
            .collect(),
        baseline_moves,
        scores: f.scores,
        resolution: None,
        ambiguous_with: (f.alternatives.iter())
            .filter(|a| a.ambiguous)
            .map(|a| a.name.clone())
            .collect(),
        alternatives: f.alternatives,
        aliasing: f.aliasing,
    }
}

#[cfg(test)]
#[path = "diagnose_tests.rs"]
mod tests;
