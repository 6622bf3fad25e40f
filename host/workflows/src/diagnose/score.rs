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
use robimu_solver::ArrowMatrix;

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
///
/// One linearisation at `at` of the model with every candidate added (θ
/// of the candidates at 0, so the residuals are `at`'s): the normal matrix
/// and gradient of `at`'s model plus one candidate are the rows and
/// columns of [c, x_a, θ_at, θ_e] of it (the effects' columns and priors
/// do not depend on which others are present), so each score restricts the
/// border to them ([`ArrowMatrix::restrict_border`]) and factors that.
pub(super) fn scores_at(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    at: &Fit,
    candidates: &[String],
) -> Result<(f64, Vec<Score>), DiagnoseError> {
    let mut all = at.effects.clone();
    all.extend(candidates.iter().cloned());
    let dofs = candidates
        .iter()
        .map(|c| Ok(effects::by_name(setup, c)?.params().len()))
        .collect::<Result<Vec<usize>, DiagnoseError>>()?;
    let (base, stats) = with_problem_at(robot, data, opts, setup, &all, at, |problem, theta| {
        let mut a = problem.new_matrix();
        let mut g = vec![0.0; theta.len()];
        problem.linearize(theta, &mut a, &mut g)?;
        // border unknowns: x_a and θ_at, then the candidates' θ in order
        let own = problem.active().len() + (problem.n_effect_params() - dofs.iter().sum::<usize>());
        let base_keep: Vec<usize> = (0..own).collect();
        let base = restricted_score(&a, &g, &base_keep, &at.effects)?;
        let mut first = own;
        let mut stats = Vec::with_capacity(candidates.len());
        for (c, &dof) in candidates.iter().zip(&dofs) {
            let keep: Vec<usize> = (0..own).chain(first..first + dof).collect();
            first += dof;
            let mut names = at.effects.clone();
            names.push(c.clone());
            stats.push(restricted_score(&a, &g, &keep, &names)?);
        }
        Ok((base, stats))
    })?;
    let mut out: Vec<Score> = candidates
        .iter()
        .zip(&dofs)
        .zip(stats)
        .map(|((c, &dof), s)| {
            let statistic = (s - base).max(0.0);
            Score {
                name: c.clone(),
                statistic,
                dof,
                p_value: chi2_sf(statistic, dof as f64),
            }
        })
        .collect();
    out.sort_by(|a, b| {
        a.p_value
            .total_cmp(&b.p_value)
            .then(b.statistic.total_cmp(&a.statistic))
    });
    Ok((base, out))
}

/// gᵀ A⁻¹ g over the band unknowns and the border unknowns `keep` of the
/// linearisation (a, g) (the model of the effects `names`, for the error).
fn restricted_score(
    a: &ArrowMatrix,
    g: &[f64],
    keep: &[usize],
    names: &[String],
) -> Result<f64, DiagnoseError> {
    let nc = a.dims().0;
    let factor = a
        .restrict_border(keep)
        .factor()
        .map_err(|e| DiagnoseError::Singular(format!("{}: {e}", names.join("+"))))?;
    let gk: Vec<f64> = g[..nc]
        .iter()
        .copied()
        .chain(keep.iter().map(|&k| g[nc + k]))
        .collect();
    let mut sol = gk.clone();
    factor.solve_in_place(&mut sol);
    Ok(gk.iter().zip(&sol).map(|(a, b)| a * b).sum())
}
