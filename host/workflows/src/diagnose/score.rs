//! The Rao score test of a candidate effect at the current fit (step 3 of
//! the diagnosis, see the module doc of [`super`]).

use std::ops::Range;

use serde::Serialize;

use super::{with_problem_at, DiagnoseError};
use crate::calibrate::fit::Fit;
use crate::calibrate::CalibrateOptions;
use crate::stats::chi2_sf;
use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use robimu_model::effects::{self, CatalogueSetup};
use robimu_model::observations::Measurements;
use robimu_model::Robot;
use robimu_solver::{ArrowMatrix, FactorError, Linearization};

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

/// [`score_all`], gᵀ A⁻¹ g of `at`'s own model (the base every score is
/// taken against) and the linearisation they came from, reduced.
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
) -> Result<(f64, Vec<Score>, ScoreSet), DiagnoseError> {
    let mut all = at.effects.clone();
    all.extend(candidates.iter().cloned());
    let dofs = candidates
        .iter()
        .map(|c| Ok(effects::by_name(setup, c)?.params().len()))
        .collect::<Result<Vec<usize>, DiagnoseError>>()?;
    let (base, stats, set) =
        with_problem_at(robot, data, opts, setup, &all, at, |problem, theta| {
            let mut a = problem.new_matrix();
            let mut g = vec![0.0; theta.len()];
            let cost = problem.linearize(theta, &mut a, &mut g)?;
            // border unknowns: x_a and θ_at, then the candidates' θ in order
            let own =
                problem.active().len() + (problem.n_effect_params() - dofs.iter().sum::<usize>());
            let reduced = Reduced::new(&a, &g).map_err(|e| singular(&at.effects, e))?;
            let base_keep: Vec<usize> = (0..own).collect();
            let base = reduced.score(&base_keep, &at.effects)?;
            let mut first = own;
            let mut stats = Vec::with_capacity(candidates.len());
            let mut blocks = Vec::with_capacity(candidates.len());
            for (c, &dof) in candidates.iter().zip(&dofs) {
                let keep: Vec<usize> = (0..own).chain(first..first + dof).collect();
                blocks.push((c.clone(), setup.spec(c), first..first + dof));
                first += dof;
                let mut names = at.effects.clone();
                names.push(c.clone());
                stats.push(reduced.score(&keep, &names)?);
            }
            let set = ScoreSet {
                reduced,
                own,
                effects: at.effects.clone(),
                blocks,
                linearized: Linearization { a, g, cost },
            };
            Ok((base, stats, set))
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
    Ok((base, out, set))
}

/// The reduced linearisation of one round's scores ([`scores_at`]): `at`'s
/// model with every candidate, from which the score of `at`'s model plus
/// any two of them is one more restriction (the effects' columns and priors
/// do not depend on which others are present), instead of a linearisation
/// of that model of its own (docs/model.md §4.9).
pub(super) struct ScoreSet {
    reduced: Reduced,
    /// Border unknowns of `at`'s own model (x_a, θ_at).
    own: usize,
    /// `at`'s effects.
    effects: Vec<String>,
    /// Per candidate: its label, its spec when scored (its resolution) and
    /// its border unknowns.
    blocks: Vec<(String, String, Range<usize>)>,
    /// The linearisation itself, unreduced (for [`Self::start_of`]).
    linearized: Linearization,
}

impl ScoreSet {
    /// gᵀ A⁻¹ g of `at`'s model plus the candidates `a` and `b`, when both
    /// were scored here at the resolutions `setup` has now (`None`
    /// otherwise: e.g. `a`'s resolution was chosen since).
    pub(super) fn joint(
        &self,
        setup: &CatalogueSetup,
        a: &str,
        b: &str,
    ) -> Option<Result<f64, DiagnoseError>> {
        let (ra, rb) = (self.block(setup, a)?, self.block(setup, b)?);
        let keep: Vec<usize> = (0..self.own).chain(ra).chain(rb).collect();
        let mut names = self.effects.clone();
        names.extend([a.to_string(), b.to_string()]);
        Some(self.reduced.score(&keep, &names))
    }
}

impl ScoreSet {
    /// The border unknowns of the candidate `name`, when it was scored here
    /// at the resolution `setup` has now.
    fn block(&self, setup: &CatalogueSetup, name: &str) -> Option<Range<usize>> {
        self.blocks
            .iter()
            .find(|(n, spec, _)| n == name && *spec == setup.spec(name))
            .map(|(_, _, r)| r.clone())
    }

    /// The linearisation of `at`'s model plus the candidate `name` at `at`
    /// (its θ at 0): the restriction of this one to its block, which is
    /// that model's own linearisation there (the effects' columns and
    /// priors do not depend on which others are present), for the refit
    /// that adds it ([`crate::calibrate::fit::Start::RefitAt`]). `None`
    /// when `name` was not scored here at the resolution `setup` has now.
    pub(super) fn start_of(&self, setup: &CatalogueSetup, name: &str) -> Option<Linearization> {
        let block = self.block(setup, name)?;
        let keep: Vec<usize> = (0..self.own).chain(block).collect();
        let lin = &self.linearized;
        let nc = lin.a.dims().0;
        let g = lin.g[..nc]
            .iter()
            .copied()
            .chain(keep.iter().map(|&k| lin.g[nc + k]))
            .collect();
        Some(Linearization {
            a: lin.a.restrict_border(&keep),
            g,
            cost: lin.cost,
        })
    }
}

/// The error of a model (the effects `names`) whose information is singular.
fn singular(names: &[String], e: FactorError) -> DiagnoseError {
    DiagnoseError::Singular(format!("{}: {e}", names.join("+")))
}

/// A linearisation (A, g) over [c, border] with the spline coefficients c
/// eliminated once, for gᵀ A⁻¹ g of many restrictions of its border
/// ([`ArrowMatrix::restrict_border`]: the models with some border unknowns
/// held fixed). With the band A_cc, the border A_cx and the corner A_xx,
///
/// ```text
/// gᵀ A⁻¹ g = g_cᵀ A_cc⁻¹ g_c + uᵀ S⁻¹ u      u = g_x − A_xc A_cc⁻¹ g_c
///                                            S = A_xx − A_xc A_cc⁻¹ A_cx
/// ```
///
/// (block elimination of c), and restricting the border to the unknowns K
/// restricts u and S to K: u_K and S_KK are those of the restricted
/// matrix, so each restriction costs the Cholesky factor of its S_KK
/// instead of a factorisation of the whole arrow matrix (band, border and
/// Schur complement; docs/model.md §4.5). Equal to the restricted
/// matrix's own gᵀ A⁻¹ g to rounding (the test below).
struct Reduced {
    /// g_cᵀ A_cc⁻¹ g_c.
    band: f64,
    /// u, one entry per border unknown.
    u: Vec<f64>,
    /// S over the whole border.
    s: Mat<f64>,
}

impl Reduced {
    fn new(a: &ArrowMatrix, g: &[f64]) -> Result<Self, FactorError> {
        let (nc, _, nx) = a.dims();
        let s = a.schur_complement()?;
        // A_cc⁻¹ g_c from the band alone (no border)
        let mut sol = g[..nc].to_vec();
        a.restrict_border(&[]).factor()?.solve_in_place(&mut sol);
        let band = g[..nc].iter().zip(&sol).map(|(a, b)| a * b).sum();
        let u = (0..nx)
            .map(|k| {
                let dot: f64 = sol
                    .iter()
                    .enumerate()
                    .map(|(i, v)| a.get(i, nc + k) * v)
                    .sum();
                g[nc + k] - dot
            })
            .collect();
        Ok(Self { band, u, s })
    }

    /// gᵀ A⁻¹ g of the restriction to the border unknowns `keep` (the
    /// model of the effects `names`, for the error).
    fn score(&self, keep: &[usize], names: &[String]) -> Result<f64, DiagnoseError> {
        let n = keep.len();
        let sk = Mat::from_fn(n, n, |i, j| self.s[(keep[i], keep[j])]);
        let llt = sk
            .llt(Side::Lower)
            .map_err(|_| singular(names, FactorError::SchurNotPositiveDefinite))?;
        let mut sol = Mat::from_fn(n, 1, |i, _| self.u[keep[i]]);
        llt.solve_in_place(sol.as_mut());
        let quad: f64 = keep
            .iter()
            .enumerate()
            .map(|(i, &k)| self.u[k] * sol[(i, 0)])
            .sum();
        Ok(self.band + quad)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// gᵀ A⁻¹ g over the band unknowns and the border unknowns `keep` of
    /// (a, g) by factoring the restricted matrix (the former score, the
    /// reference of [`Reduced`]).
    fn restricted_score(a: &ArrowMatrix, g: &[f64], keep: &[usize]) -> f64 {
        let nc = a.dims().0;
        let factor = a.restrict_border(keep).factor().unwrap();
        let gk: Vec<f64> = g[..nc]
            .iter()
            .copied()
            .chain(keep.iter().map(|&k| g[nc + k]))
            .collect();
        let mut sol = gk.clone();
        factor.solve_in_place(&mut sol);
        gk.iter().zip(&sol).map(|(a, b)| a * b).sum()
    }

    /// The reduced scores of a random arrowhead normal matrix (JᵀJ of
    /// banded rows with a dense border, plus a diagonal prior) equal the
    /// restricted matrices' own gᵀ A⁻¹ g, for the whole border, parts of
    /// it and none of it.
    #[test]
    fn reduced_scores_equal_the_restricted_factorisations() {
        use faer::Mat as M;
        let (nc, w, nx) = (40, 3, 9);
        let mut a = ArrowMatrix::zeros(nc, w, nx);
        let val = |i: usize, k: usize| ((i * 31 + k * 17) as f64 * 0.613).sin();
        let mut g = vec![0.0; nc + nx];
        // rows touching w + 1 consecutive coefficients and every border unknown
        for r in 0..nc - w {
            let nl = w + 1;
            let row: Vec<f64> = (0..nl + nx).map(|k| val(r, k)).collect();
            let local = M::from_fn(nl + nx, nl + nx, |i, j| row[i] * row[j]);
            let idx: Vec<usize> = (0..nx).collect();
            a.add_local(r, nl, &idx, local.as_ref());
            let res = val(r, 99);
            for (k, v) in row.iter().enumerate() {
                let at = if k < nl { r + k } else { nc + k - nl };
                g[at] += v * res;
            }
        }
        let mut prior = vec![0.5; nc + nx];
        prior[nc..]
            .iter_mut()
            .enumerate()
            .for_each(|(k, p)| *p = 0.1 + 0.01 * k as f64);
        a.add_diagonal(&prior);
        let reduced = Reduced::new(&a, &g).unwrap();
        let keeps: [Vec<usize>; 5] = [
            (0..nx).collect(),
            (0..5).collect(),
            vec![0, 1, 2, 3, 4, 7, 8],
            vec![6],
            vec![],
        ];
        for keep in keeps {
            let want = restricted_score(&a, &g, &keep);
            let got = reduced.score(&keep, &[]).unwrap();
            println!("{keep:?}: {got} vs {want}");
            assert!(
                (got - want).abs() <= 1e-12 * want.abs(),
                "{keep:?}: {got} vs {want}"
            );
        }
    }
}
