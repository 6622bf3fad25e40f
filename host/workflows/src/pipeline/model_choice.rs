//! Which model `robimu calibrate` writes (docs/model.md §8.6): the
//! diagnosis's search ([`crate::diagnose`]: the same score tests,
//! false-alarm control, ambiguity and no-cascade rules — one
//! implementation) from the paper's white fit; when it adds an effect, its
//! final model is the result; when it adds none, the paper's fit is, with
//! the score test of every catalogue effect at it. The records of
//! result.json that say so: the effects and why each was added, and the
//! tests the written model passes or fails.

use robimu_model::effects::{self, CatalogueSetup};
use robimu_model::observations::Measurements;
use robimu_model::Robot;
use robimu_session::result::{
    EffectEvidence, EffectParameterRecord, EffectRecord, ModelTestsRecord, SignificantEffect,
};

use crate::calibrate::fit::Fit;
use crate::calibrate::CalibrateOptions;
use crate::diagnose::{offered_candidates, score_all, DiagnoseError, Diagnosis, Score};

/// Which model a calibration fits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ModelChoice {
    /// The paper's model, tested; the effects the tests ask for added
    /// (calibrate's default).
    #[default]
    Select,
    /// The paper's model alone (`--model paper`), tested but never extended.
    Paper,
}

/// Family-wise level of the model tests (diagnose's default `--alpha`).
pub(crate) const MODEL_ALPHA: f64 = 0.01;

/// The score tests of the catalogue against a fitted model.
#[derive(Debug, Clone)]
pub(crate) struct ModelTests {
    /// Every candidate's score, best first.
    pub scores: Vec<Score>,
    /// The candidates offered (the Bonferroni count).
    pub candidates: usize,
    /// α / candidates.
    pub threshold: f64,
}

impl ModelTests {
    /// The record, every significant candidate with `reason`.
    pub(crate) fn record(&self, selection: &str, reason: &str) -> ModelTestsRecord {
        let (significant, rest): (Vec<&Score>, Vec<&Score>) =
            self.scores.iter().partition(|s| s.p_value < self.threshold);
        ModelTestsRecord {
            selection: selection.into(),
            alpha: MODEL_ALPHA,
            candidates: self.candidates,
            significant: significant
                .into_iter()
                .map(|s| SignificantEffect {
                    name: s.name.clone(),
                    p_value: s.p_value,
                    reason: reason.into(),
                })
                .collect(),
            largest_remaining: rest.first().map(|s| SignificantEffect {
                name: s.name.clone(),
                p_value: s.p_value,
                reason: String::new(),
            }),
        }
    }
}

/// Every catalogue candidate not in `f`'s model scored at `f` under its
/// noise model (the diagnosis's first round, without its refits).
pub(crate) fn test_model(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    f: &Fit,
) -> Result<ModelTests, DiagnoseError> {
    let all: Vec<String> = effects::NAMES.iter().map(|s| s.to_string()).collect();
    let offered = offered_candidates(setup, &all, &f.effects);
    let threshold = MODEL_ALPHA / offered.len().max(1) as f64;
    let ropts = CalibrateOptions {
        noise: (!f.noise.is_white()).then(|| f.noise.clone()),
        ..opts.clone()
    };
    let scores = match offered.is_empty() {
        true => Vec::new(),
        false => score_all(robot, data, &ropts, setup, f, &offered)?,
    };
    Ok(ModelTests {
        scores,
        candidates: offered.len(),
        threshold,
    })
}

/// The tests of a diagnosis's final model: the candidates it rejected (not
/// determined apart from the effects added, or a failed refit) and those
/// its last round found significant but whose refit's likelihood ratio did
/// not confirm them, with why.
pub(crate) fn selection_tests(d: &Diagnosis, selection: &str) -> ModelTestsRecord {
    let tests = ModelTests {
        scores: d.last_scores.clone(),
        candidates: d.candidates,
        threshold: d.threshold,
    };
    let mut record = tests.record(
        selection,
        "its refit's likelihood ratio did not confirm it (robimu diagnose shows the evidence)",
    );
    for r in &d.rejected {
        if !record.significant.iter().any(|s| s.name == r.name) {
            record.significant.push(SignificantEffect {
                name: r.name.clone(),
                p_value: r.p_value,
                reason: r.reason.clone(),
            });
        }
    }
    record
}

/// The effects of the final fit `f` (`setup` gives their specs), each with
/// its parameters and, when the search added it, its evidence.
pub(crate) fn effect_records(
    f: &Fit,
    setup: &CatalogueSetup,
    d: Option<&Diagnosis>,
) -> Vec<EffectRecord> {
    f.effects
        .iter()
        .map(|name| {
            let prefix = format!("{name}.");
            let parameters = f
                .effect_params
                .iter()
                .enumerate()
                .filter(|(_, p)| p.name.starts_with(&prefix))
                .map(|(e, p)| EffectParameterRecord {
                    name: p.name.clone(),
                    unit: p.unit.to_string(),
                    value: f.theta_e[e],
                    sigma: f.sigma_e[e],
                })
                .collect();
            let evidence = d
                .and_then(|d| d.found.iter().find(|e| &e.name == name))
                .map(|e| EffectEvidence {
                    statistic: e.statistic,
                    dof: e.dof,
                    p_value: e.p_value,
                    lr_statistic: e.lr_statistic,
                    lr_p_value: e.lr_p_value,
                    rms_before: e.rms_before,
                    rms_after: e.rms_after,
                });
            EffectRecord {
                name: name.clone(),
                spec: setup.spec(name),
                parameters,
                evidence,
            }
        })
        .collect()
}
