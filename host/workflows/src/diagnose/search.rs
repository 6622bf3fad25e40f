//! Steps 3–4 of the diagnosis (docs/model.md §7): from the baseline fit,
//! add significant effects one at a time from the offered candidates
//! (Bonferroni threshold α/|offered|). Each [`round`] scores the candidates
//! at the current fit and either ends the search (none significant, or the
//! best one's refit not confirmed by its likelihood ratio), rejects the best
//! one (its refit failed, or it is not determined apart from the effects
//! already added) or adds it.

use robimu_model::effects::CatalogueSetup;
use robimu_model::observations::Measurements;
use robimu_model::{ParamLayout, Robot};

use super::score::{scores_at, Score};
use super::{
    effect_imu, fit_effects, identify_imus_at, ranking, resolution, settle_noise, with_noise_of,
    AddedParameter, DiagnoseError, DiagnoseOptions, FoundEffect, NoiseUse, ParameterMove, Rejected,
};
use crate::calibrate::fit::{Fit, Start};
use crate::calibrate::noise_choice::NoiseChoice;
use crate::calibrate::{CalibrateError, CalibrateOptions};
use crate::stats::chi2_sf;

/// What a search runs on.
pub(super) struct SearchProblem<'a> {
    /// The robot.
    pub robot: &'a Robot,
    /// The session's measurements.
    pub data: &'a Measurements,
    /// The calibration options (their noise is the current fit's in each round).
    pub opts: &'a CalibrateOptions,
    /// The diagnosis options.
    pub dopts: &'a DiagnoseOptions,
    /// The candidates offered (the Bonferroni count).
    pub offered: &'a [String],
}

/// What a search ends with.
pub(super) struct Search {
    /// The final fit.
    pub fit: Fit,
    /// The effects added, in order.
    pub found: Vec<FoundEffect>,
    /// The candidates rejected.
    pub rejected: Vec<Rejected>,
    /// The scores of the last round (empty when no candidate was left).
    pub last_scores: Vec<Score>,
    /// The noise model's use.
    pub noise: NoiseUse,
}

/// How a round ended.
enum Round {
    /// The search ends with this round's scores.
    Done(Vec<Score>),
    /// The best candidate is rejected; the next round goes on without it.
    Rejected(Rejected),
    /// The best candidate is added.
    Added(Box<Added>),
}

/// An effect added: the refit with it and its record.
struct Added {
    fit: Fit,
    found: FoundEffect,
}

impl SearchProblem<'_> {
    /// The Bonferroni threshold α/|offered|.
    fn threshold(&self) -> f64 {
        self.dopts.alpha / self.offered.len().max(1) as f64
    }
}

/// The search from the fit `baseline` (its noise use `noise`); `setup` gets
/// the resolutions chosen.
pub(super) fn search_effects(
    p: &SearchProblem<'_>,
    setup: &mut CatalogueSetup,
    baseline: &Fit,
    noise: NoiseUse,
    mut progress: impl FnMut(&str),
) -> Result<Search, DiagnoseError> {
    let mut s = Search {
        fit: baseline.clone(),
        found: Vec::new(),
        rejected: Vec::new(),
        last_scores: Vec::new(),
        noise,
    };
    let n_res = 6.0 * baseline.residuals.len() as f64;
    loop {
        match round(p, setup, &mut s, n_res, &mut progress)? {
            Round::Done(scores) => {
                s.last_scores = scores;
                return Ok(s);
            }
            Round::Rejected(r) => s.rejected.push(r),
            Round::Added(a) => {
                s.found.push(a.found);
                s.fit = a.fit;
            }
        }
    }
}

/// One round at the current fit `s.fit` (`n_res`: the residual count of
/// the ΔBIC).
fn round(
    p: &SearchProblem<'_>,
    setup: &mut CatalogueSetup,
    s: &mut Search,
    n_res: f64,
    progress: &mut impl FnMut(&str),
) -> Result<Round, DiagnoseError> {
    let (robot, data) = (p.robot, p.data);
    let current = &s.fit;
    let candidates: Vec<String> = p
        .offered
        .iter()
        .filter(|c| !current.effects.contains(c) && !s.rejected.iter().any(|r| &r.name == *c))
        .cloned()
        .collect();
    // at the limit the candidates are still scored (the tests of the
    // final model) unless the limit is 0 effects and none were asked for
    let at_limit = s.found.len() >= p.dopts.max_effects;
    if candidates.is_empty() || (at_limit && p.dopts.max_effects > 0) {
        return Ok(Round::Done(Vec::new()));
    }
    // scores, refit and LR under the current fit's noise model
    let threshold = p.threshold();
    let ropts = with_noise_of(p.opts, current);
    progress("scoring the candidate effects");
    let (base_q, scores, set) = scores_at(robot, data, &ropts, setup, current, &candidates)?;
    let mut best = scores[0].clone();
    if best.p_value >= threshold || at_limit {
        return Ok(Round::Done(scores));
    }
    let resolution =
        resolution::choose(robot, data, &ropts, setup, current, &best)?.map(|(choice, score)| {
            progress(&format!(
                "{}: resolution {} chosen",
                best.name, choice.chosen
            ));
            best = score;
            choice
        });
    progress(&format!("refitting with {}", best.name));
    let mut names = current.effects.clone();
    names.push(best.name.clone());
    // its refit starts from the scores' linearisation, restricted to it
    let given = set.start_of(setup, &best.name);
    let start = match &given {
        Some(at) => Start::RefitAt(current, at),
        None => Start::Refit(current),
    };
    let next = match fit_effects(robot, data, &ropts, setup, &names, start) {
        Ok(f) => f,
        // a candidate whose refit fails is not confirmed; the diagnosis goes on
        Err(DiagnoseError::Calibrate(
            e @ (CalibrateError::NotConverged { .. } | CalibrateError::Solver(_)),
        )) => {
            progress(&format!("{}: its refit failed ({e}); not added", best.name));
            return Ok(Round::Rejected(refit_failed(&best, &e)));
        }
        Err(e) => return Err(e),
    };
    let lr = 2.0 * (current.cost - next.cost);
    let lr_p = chi2_sf(lr, best.dof as f64);
    if lr_p >= threshold {
        return Ok(Round::Done(scores));
    }
    // a follow-up must be determined apart from the effects already added
    let det = match s.found.is_empty() {
        true => None,
        false => Some(ranking::determination(setup, &next)?),
    };
    if let Some(det) = det.as_ref().filter(|d| d.aliasing > p.dopts.max_aliasing) {
        return Ok(Round::Rejected(not_determined(
            &best,
            lr,
            det,
            p.dopts.max_aliasing,
        )));
    }
    // the winner at its chosen resolution (the setup has it now)
    let mut ranked = scores.clone();
    ranked[0] = best.clone();
    let alternatives = ranking::alternatives(
        robot, data, &ropts, setup, current, base_q, &set, &ranked, threshold,
    )?;
    let ambiguous_with = alternatives
        .iter()
        .filter(|a| a.ambiguous)
        .map(|a| a.name.clone())
        .collect();
    let aliasing = det.map_or(0.0, |d| d.aliasing);
    let next = match p.dopts.noise {
        NoiseChoice::Auto => reidentified(p, setup, next, &best.name, &mut s.noise, progress),
        _ => next,
    };
    let current = &s.fit;
    let found = FoundEffect {
        name: best.name.clone(),
        imu: effect_imu(&best.name),
        statistic: best.statistic,
        dof: best.dof,
        p_value: best.p_value,
        lr_statistic: lr,
        lr_p_value: lr_p,
        delta_bic: -lr + best.dof as f64 * n_res.ln(),
        rms_before: current.residual_rms(),
        rms_after: next.residual_rms(),
        parameters: added_parameters(current, &next),
        baseline_moves: baseline_moves(
            &ParamLayout::with_imus(robot, data.n_imus()),
            current,
            &next,
        ),
        scores,
        resolution,
        alternatives,
        ambiguous_with,
        aliasing,
    };
    Ok(Round::Added(Box::new(Added { fit: next, found })))
}

/// `next` with its noise identified again (`auto`): the effect's signal was
/// in the residuals the noise was identified from. A failure keeps its
/// noise model, with a warning.
fn reidentified(
    p: &SearchProblem<'_>,
    setup: &CatalogueSetup,
    next: Fit,
    name: &str,
    noise: &mut NoiseUse,
    progress: &mut impl FnMut(&str),
) -> Fit {
    let (robot, data, opts, id_opts) = (p.robot, p.data, p.opts, &p.dopts.noise_id);
    progress("identifying the noise again");
    let settle = (id_opts, &p.dopts.settle);
    let settled = identify_imus_at(robot, data, opts, setup, &next, id_opts)
        .and_then(|ids| settle_noise(robot, data, opts, setup, &next, ids, settle, progress));
    match settled {
        Ok((f, refits)) => {
            if refits > 0 {
                noise.reidentified_after.push(name.to_string());
            }
            f
        }
        Err(e) => {
            noise
                .warnings
                .push(format!("after adding {name}: {e}; its noise model kept"));
            next
        }
    }
}

/// The effect parameters `next` has beyond `current`'s.
fn added_parameters(current: &Fit, next: &Fit) -> Vec<AddedParameter> {
    (current.theta_e.len()..next.theta_e.len())
        .map(|e| {
            let p = &next.effect_params[e];
            AddedParameter {
                name: p.name.clone(),
                unit: p.unit.to_string(),
                value: next.theta_e[e],
                sigma: next.sigma_e[e],
            }
        })
        .collect()
}

/// The parameters of x that moved by more than their σ from `current` to
/// `next`.
fn baseline_moves(layout: &ParamLayout, current: &Fit, next: &Fit) -> Vec<ParameterMove> {
    layout
        .specs()
        .iter()
        .enumerate()
        .filter(|(k, _)| {
            next.sigma_x[*k] > 0.0 && (next.x[*k] - current.x[*k]).abs() > next.sigma_x[*k]
        })
        .map(|(k, s)| ParameterMove {
            name: s.name.clone(),
            before: current.x[k],
            after: next.x[k],
            sigma: next.sigma_x[k],
        })
        .collect()
}

/// The candidate `best`, whose refit failed with `e`.
fn refit_failed(best: &Score, e: &CalibrateError) -> Rejected {
    Rejected {
        name: best.name.clone(),
        statistic: best.statistic,
        dof: best.dof,
        p_value: best.p_value,
        lr_statistic: f64::NAN,
        aliasing: f64::NAN,
        aliased_with: None,
        reason: format!("its refit failed: {e}"),
    }
}

/// The candidate `best` (refit's LR statistic `lr`), not determined apart
/// from the effects already added (`det`, above `max_aliasing`).
fn not_determined(
    best: &Score,
    lr: f64,
    det: &ranking::Determination,
    max_aliasing: f64,
) -> Rejected {
    let with = det.most_with.as_ref().map_or(String::new(), |m| {
        format!(" (most with {}: ρ² {:.3})", m.name, m.rho2)
    });
    Rejected {
        name: best.name.clone(),
        statistic: best.statistic,
        dof: best.dof,
        p_value: best.p_value,
        lr_statistic: lr,
        aliasing: det.aliasing,
        aliased_with: det.most_with.clone(),
        reason: format!(
            "not determined apart from the effects already added: ρ²_max {:.3} > {max_aliasing}{with}",
            det.aliasing
        ),
    }
}
