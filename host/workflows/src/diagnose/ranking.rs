//! Ranking and stopping (docs/model.md §4.9): which other candidates
//! explain the same signal as a round's winner (ambiguity), and whether a
//! follow-up effect's own parameters are determined apart from the effects
//! already added (no cascades).
//!
//! **Ambiguity.** With S(e) the efficient score of a candidate at the
//! current fit and S(a∪b) that of two together (one more linearisation),
//! the conditional scores
//!
//! ```text
//! S(b | a) = S(a∪b) − S(a)      S(a | b) = S(a∪b) − S(b)
//! ```
//!
//! are the score tests of b with a also in the model and of a with b
//! (nested: ~ χ²(k_b), χ²(k_a) under their nulls). A candidate b that is
//! significant alone is *ambiguous* with the winner a when neither adds
//! significantly to the other (both conditional p ≥ the Bonferroni
//! threshold): the data cannot tell a from b, either one alone explains
//! what they explain together. `shared` = 1 − S(b|a)/S(b) is the fraction
//! of b's score that a explains (for one parameter each and a signal of
//! b's form, ρ² of their efficient scores' correlation ρ).
//!
//! **Determination.** A follow-up effect b (after at least one effect was
//! added) must also be determined apart from the effects E already added:
//! from the refit's information J over [x_a, θ_E, θ_b], the information
//! about θ_b with everything else estimated, I_b = (Σ_bb)⁻¹, against the
//! same with E known, I⁰_b = ((J restricted to [x_a, θ_b])⁻¹)_bb. The
//! generalised eigenvalues μ_i of I_b against I⁰_b are 1 − ρ_i², ρ_i the
//! canonical correlations between b's and E's efficient scores (the
//! baseline partialled out); b is rejected when ρ²_max > [`MAX_ALIASING`]:
//! along some direction of its parameters it keeps less than 1 − 0.9 =
//! 10 % of its information once E is estimated too (σ inflated more than
//! √10 ≈ 3.2×, the usual variance-inflation limit of 10), i.e. its
//! estimate trades against an effect already there rather than
//! describing a signal of its own — the small follow-ups that soak up
//! what a mis-modelled effect left.

use std::ops::Range;

use faer::{Mat, Side};
use serde::Serialize;

use super::score::{quadratic_score, Score, ScoreSet};
use super::{AliasedWith, DiagnoseError};
use crate::calibrate::fit::Fit;
use crate::calibrate::CalibrateOptions;
use crate::stats::chi2_sf;
use robimu_model::effects::{self, CatalogueSetup};
use robimu_model::observations::Measurements;
use robimu_model::Robot;

/// Largest ρ² between a follow-up effect's and the added effects'
/// efficient scores (the module doc: variance inflation above 10).
pub const MAX_ALIASING: f64 = 0.9;

/// A candidate significant alone in a round, compared with its winner a
/// at the same fit.
#[derive(Debug, Clone, Serialize)]
pub struct Alternative {
    /// Effect name (b).
    pub name: String,
    /// S(b), its score alone.
    pub statistic: f64,
    /// Its degrees of freedom.
    pub dof: usize,
    /// S(b | a) = S(a∪b) − S(a).
    pub given_winner: f64,
    /// P(χ²(k_b) > S(b | a)).
    pub given_winner_p: f64,
    /// S(a | b) = S(a∪b) − S(b).
    pub winner_given_it: f64,
    /// P(χ²(k_a) > S(a | b)).
    pub winner_given_it_p: f64,
    /// 1 − S(b | a) / S(b): the part of b's score a explains.
    pub shared: f64,
    /// Neither adds significantly to the other.
    pub ambiguous: bool,
}

/// Every candidate of `scores` (sorted, the winner first) significant
/// alone (p < `threshold`) compared with the winner; `base` is gᵀA⁻¹g of
/// `at`'s own model and `set` the round's linearisation
/// ([`super::score::scores_at`]): S(a∪b) is a restriction of it where it
/// has both at their current resolutions, else one linearisation of its
/// own.
#[allow(clippy::too_many_arguments)]
pub(super) fn alternatives(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    at: &Fit,
    base: f64,
    set: &ScoreSet,
    scores: &[Score],
    threshold: f64,
) -> Result<Vec<Alternative>, DiagnoseError> {
    let Some((a, rest)) = scores.split_first() else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for b in rest.iter().filter(|b| b.p_value < threshold) {
        let mut names = at.effects.clone();
        names.extend([a.name.clone(), b.name.clone()]);
        let joint = match set.joint(setup, &a.name, &b.name) {
            Some(q) => q?,
            None => quadratic_score(robot, data, opts, setup, &names, at)?,
        };
        out.push(compare(a, b, (joint - base).max(0.0), threshold));
    }
    Ok(out)
}

/// The [`Alternative`] of `b` against the winner `a` from their scores
/// alone and S(a∪b) `joint` (all against the same model; the module doc).
pub(crate) fn compare(a: &Score, b: &Score, joint: f64, threshold: f64) -> Alternative {
    let given_winner = (joint - a.statistic).max(0.0);
    let winner_given_it = (joint - b.statistic).max(0.0);
    let given_winner_p = chi2_sf(given_winner, b.dof as f64);
    let winner_given_it_p = chi2_sf(winner_given_it, a.dof as f64);
    Alternative {
        name: b.name.clone(),
        statistic: b.statistic,
        dof: b.dof,
        given_winner,
        given_winner_p,
        winner_given_it,
        winner_given_it_p,
        shared: 1.0 - given_winner / b.statistic.max(f64::MIN_POSITIVE),
        ambiguous: given_winner_p >= threshold && winner_given_it_p >= threshold,
    }
}

/// How well the last effect of a fit is determined apart from the effects
/// before it (the module doc).
#[derive(Debug, Clone, Serialize)]
pub struct Determination {
    /// ρ²_max against all of them together (0 with none).
    pub aliasing: f64,
    /// The single earlier effect with the largest ρ²_max, and that ρ²_max.
    pub most_with: Option<AliasedWith>,
}

/// The [`Determination`] of `f`'s last effect.
pub fn determination(setup: &CatalogueSetup, f: &Fit) -> Result<Determination, DiagnoseError> {
    let na = f.active.len();
    let mut ranges = Vec::new();
    let mut off = na;
    for name in &f.effects {
        let k = effects::by_name(setup, name)?.params().len();
        ranges.push((name.clone(), off..off + k));
        off += k;
    }
    let Some((_, b)) = ranges.pop() else {
        return Ok(Determination {
            aliasing: 0.0,
            most_with: None,
        });
    };
    let singular =
        || DiagnoseError::Singular(format!("the information of {}", f.effects.join("+")));
    let all: Vec<_> = ranges.iter().map(|(_, r)| r.clone()).collect();
    let total = aliasing(&f.information, &f.covariance, &all, &b).ok_or_else(singular)?;
    let mut most_with: Option<AliasedWith> = None;
    for (name, r) in &ranges {
        let a = aliasing(&f.information, &f.covariance, std::slice::from_ref(r), &b)
            .ok_or_else(singular)?;
        if most_with.as_ref().is_none_or(|m| a > m.rho2) {
            most_with = Some(AliasedWith {
                name: name.clone(),
                rho2: a,
            });
        }
    }
    Ok(Determination {
        aliasing: total,
        most_with,
    })
}

/// ρ²_max between the parameters `b` (the last block) and the `known`
/// blocks, from the information `info` over all parameters and its
/// inverse `cov` (the module doc); None when a matrix is not positive
/// definite.
pub(crate) fn aliasing(
    info: &Mat<f64>,
    cov: &Mat<f64>,
    known: &[Range<usize>],
    b: &Range<usize>,
) -> Option<f64> {
    let nb = b.len();
    let sub = |m: &Mat<f64>, idx: &[usize]| {
        Mat::from_fn(idx.len(), idx.len(), |i, j| m[(idx[i], idx[j])])
    };
    let bi: Vec<usize> = b.clone().collect();
    // I_b: the information about θ_b with all else estimated
    let i_b = inverse(&sub(cov, &bi))?;
    // I⁰_b: the same with the `known` blocks known (left out of J)
    let keep: Vec<usize> = (0..info.nrows())
        .filter(|i| !known.iter().any(|r| r.contains(i)))
        .collect();
    let cov0 = inverse(&sub(info, &keep))?;
    let s0 = keep.len() - nb;
    let i0 = inverse(&Mat::from_fn(nb, nb, |i, j| cov0[(s0 + i, s0 + j)]))?;
    let mu = generalised_min_eigenvalue(&i_b, &i0)?;
    Some((1.0 - mu).clamp(0.0, 1.0))
}

/// The inverse of a symmetric positive-definite matrix (None otherwise).
fn inverse(m: &Mat<f64>) -> Option<Mat<f64>> {
    use faer::linalg::solvers::DenseSolveCore;
    m.llt(Side::Lower).ok().map(|l| l.inverse())
}

/// The smallest μ with A v = μ B v (A, B symmetric, B positive definite):
/// with B = V D Vᵀ and W = V D^(−1/2), the smallest eigenvalue of Wᵀ A W.
fn generalised_min_eigenvalue(a: &Mat<f64>, b: &Mat<f64>) -> Option<f64> {
    let evd = b.self_adjoint_eigen(Side::Lower).ok()?;
    let (s, u) = (evd.S(), evd.U());
    let n = b.nrows();
    if (0..n).any(|i| s[i] <= 0.0) {
        return None;
    }
    let w = Mat::from_fn(n, n, |i, j| u[(i, j)] / s[j].sqrt());
    let m = w.transpose() * a * &w;
    let sym = Mat::from_fn(n, n, |i, j| 0.5 * (m[(i, j)] + m[(j, i)]));
    let ev = sym.self_adjoint_eigenvalues(Side::Lower).ok()?;
    Some(ev.iter().copied().fold(f64::INFINITY, f64::min))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ρ² of one new parameter against one earlier one, the baseline
    /// (two columns) partialled out, against the squared correlation of
    /// their columns' least-squares residuals on the baseline columns
    /// (Gram–Schmidt), for a design X with J = XᵀX; and with nothing known
    /// the aliasing is 0.
    #[test]
    fn aliasing_is_the_squared_partial_correlation() {
        let n = 400;
        let col = |k: usize, i: usize| ((i * (7 + 3 * k) + k * k) as f64 * 0.37).sin();
        // x0, x1 baseline; e earlier effect; b = 0.8 e + 0.5 x0 + own part
        let x: Vec<[f64; 4]> = (0..n)
            .map(|i| {
                let (x0, x1, e, own) = (col(0, i), col(1, i), col(2, i), col(3, i));
                [x0, x1, e + 0.3 * x1, 0.8 * e + 0.5 * x0 + 0.4 * own]
            })
            .collect();
        let info = Mat::from_fn(4, 4, |i, j| x.iter().map(|r| r[i] * r[j]).sum());
        let cov = inverse(&info).unwrap();
        let got = aliasing(&info, &cov, std::slice::from_ref(&(2..3)), &(3..4)).unwrap();
        // reference: residuals of e and b on span(x0, x1), then corr²
        let mut basis: Vec<Vec<f64>> = Vec::new();
        for k in 0..2 {
            let mut v: Vec<f64> = x.iter().map(|r| r[k]).collect();
            for u in &basis {
                let d: f64 = v.iter().zip(u).map(|(a, b)| a * b).sum();
                v.iter_mut().zip(u).for_each(|(a, b)| *a -= d * b);
            }
            let norm = v.iter().map(|a| a * a).sum::<f64>().sqrt();
            basis.push(v.iter().map(|a| a / norm).collect());
        }
        let resid = |k: usize| {
            let mut v: Vec<f64> = x.iter().map(|r| r[k]).collect();
            for u in &basis {
                let d: f64 = v.iter().zip(u).map(|(a, b)| a * b).sum();
                v.iter_mut().zip(u).for_each(|(a, b)| *a -= d * b);
            }
            v
        };
        let (re, rb) = (resid(2), resid(3));
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let want = dot(&re, &rb).powi(2) / (dot(&re, &re) * dot(&rb, &rb));
        println!("ρ² {got} vs {want}");
        assert!(want > 0.5 && want < 0.95, "{want}");
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        assert!(aliasing(&info, &cov, &[], &(3..4)).unwrap().abs() < 1e-12);
    }

    /// The generalised eigenvalue against a direct 2×2 formula: for
    /// B = I the eigenvalues of A; for diagonal B those of B^(−1/2) A B^(−1/2).
    #[test]
    fn generalised_eigenvalue_matches_closed_form() {
        let a = Mat::from_fn(2, 2, |i, j| [[2.0, 0.6], [0.6, 1.0]][i][j]);
        let b = Mat::from_fn(2, 2, |i, j| [[4.0, 0.0], [0.0, 1.0]][i][j]);
        // B^(−1/2) A B^(−1/2) = [[0.5, 0.3], [0.3, 1.0]]
        let (p, q, r) = (0.5f64, 0.3f64, 1.0f64);
        let want = 0.5 * (p + r) - (0.25 * (p - r).powi(2) + q * q).sqrt();
        let got = generalised_min_eigenvalue(&a, &b).unwrap();
        assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        let id = Mat::from_fn(2, 2, |i, j| if i == j { 1.0 } else { 0.0 });
        let want = 1.5 - (0.25 + 0.36f64).sqrt();
        assert!((generalised_min_eigenvalue(&a, &id).unwrap() - want).abs() < 1e-12);
    }
}
