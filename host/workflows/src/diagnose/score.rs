//! The Rao score test of a candidate effect at the current fit (step 3 of
//! the diagnosis, see the module doc of [`super`]).

use serde::Serialize;

use super::{with_problem_at, DiagnoseError};
use crate::calibrate::fit::Fit;
use crate::calibrate::CalibrateOptions;
use crate::stats::chi2_sf;
use robimu_model::effects::{self, CatalogueSetup};
use robimu_model::observations::Measurements;
use robimu_model::Robot;

/// gᵀ A⁻¹ g of the problem with `names` effects at the fit `at`.
pub(super) fn quadratic_score(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    names: &[String],
    at: &Fit,
) -> Result<f64, DiagnoseError> {
    with_problem_at(robot, data, opts, setup, names, at, |problem, theta| {
        let mut a = problem.new_matrix();
        let mut g = vec![0.0; theta.len()];
        problem.linearize(theta, &mut a, &mut g)?;
        let factor = a
            .factor()
            .map_err(|e| DiagnoseError::Singular(format!("{}: {e}", names.join("+"))))?;
        let mut sol = g.clone();
        factor.solve_in_place(&mut sol);
        Ok(g.iter().zip(&sol).map(|(a, b)| a * b).sum())
    })
}

/// The outcome of one score test.
#[derive(Debug, Clone, Serialize)]
pub struct Score {
    /// Effect name.
    pub name: String,
    /// Rao score statistic.
    pub statistic: f64,
    /// Degrees of freedom k (parameters of the effect).
    pub dof: usize,
    /// P(χ²_k > statistic).
    pub p_value: f64,
}

/// Score every effect of `candidates` at the fit `at` (no refit).
pub fn score_all(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    at: &Fit,
    candidates: &[String],
) -> Result<Vec<Score>, DiagnoseError> {
    Ok(scores_at(robot, data, opts, setup, at, candidates)?.1)
}

/// [`score_all`] and gᵀ A⁻¹ g of `at`'s own model (the base every score
/// is taken against).
pub(super) fn scores_at(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    at: &Fit,
    candidates: &[String],
) -> Result<(f64, Vec<Score>), DiagnoseError> {
    let base = quadratic_score(robot, data, opts, setup, &at.effects, at)?;
    let mut out = Vec::new();
    for c in candidates {
        let mut names = at.effects.clone();
        names.push(c.clone());
        let dof = effects::by_name(setup, c)?.params().len();
        let s = quadratic_score(robot, data, opts, setup, &names, at)?;
        let statistic = (s - base).max(0.0);
        out.push(Score {
            name: c.clone(),
            statistic,
            dof,
            p_value: chi2_sf(statistic, dof as f64),
        });
    }
    out.sort_by(|a, b| {
        a.p_value
            .total_cmp(&b.p_value)
            .then(b.statistic.total_cmp(&a.statistic))
    });
    Ok((base, out))
}
