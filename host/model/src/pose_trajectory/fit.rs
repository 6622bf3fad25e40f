//! A [`PoseSpline`] through pose samples (t, p̃, q̃) (MODEL.md §10's
//! `poses.csv`): the position by the linear least-squares B-spline fit
//! ([`Spline::fit`]); the rotation control points first by slerp of the
//! samples around each control point's Greville abscissa, then refined by
//! Levenberg–Marquardt on Σ |Log(R̃ᵀ R(t))|² (the §10 rotation residual),
//! with the banded normal equations in the local parameters δ_k.
//!
//! Quaternion signs do not matter: q and −q give the same matrix
//! ([`matrix_from_quat`]), and everything after works on matrices.

use super::{Jac3x12, PoseSpline, PoseSplineError, DEGREE, LOCAL};
use crate::geom::{dot, log_so3, matrix_from_quat, mul_mm, scale, transpose, M3, V3};
use crate::spline::{Knots, Spline, SplineError};

/// Most Levenberg–Marquardt iterations of [`PoseSpline::fit`].
const MAX_ITERATIONS: usize = 50;
/// The refinement stops when no local step component exceeds this (rad).
const STEP_TOLERANCE: f64 = 1e-12;

/// How a fit went.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitReport {
    /// Levenberg–Marquardt iterations of the rotation refinement.
    pub iterations: usize,
    /// Whether the refinement reached its step tolerance (or could improve no more).
    pub converged: bool,
    /// RMS of |e_p| over the samples (m).
    pub rms_position: f64,
    /// RMS of |e_r| over the samples (rad).
    pub rms_rotation: f64,
}

/// Banded symmetric normal equations in the 3m local rotation parameters
/// (`band[i·BW + d]` = A[i][i−d]; a sample touches 12 consecutive unknowns).
struct Normal {
    band: Vec<f64>,
    rhs: Vec<f64>,
}

const BW: usize = LOCAL;

impl Normal {
    fn zero(n: usize) -> Self {
        Self {
            band: vec![0.0; n * BW],
            rhs: vec![0.0; n],
        }
    }

    /// Add JᵀJ and −Jᵀe of one sample whose control points start at `first`.
    fn add(&mut self, first: usize, jac: &Jac3x12, e: &V3) {
        let base = 3 * first;
        for a in 0..LOCAL {
            for c in 0..=a {
                let v: f64 = (0..3).map(|r| jac[r][a] * jac[r][c]).sum();
                self.band[(base + a) * BW + (a - c)] += v;
            }
            self.rhs[base + a] -= (0..3).map(|r| jac[r][a] * e[r]).sum::<f64>();
        }
    }

    /// Solve (A + λ·(diag A + 10⁻⁹·max diag A)) x = rhs by banded Cholesky.
    fn solve(&self, lambda: f64) -> Result<Vec<f64>, SplineError> {
        let n = self.rhs.len();
        let mut l = self.band.clone();
        let max_diag = (0..n).map(|i| l[i * BW]).fold(0.0, f64::max);
        for i in 0..n {
            l[i * BW] += lambda * (l[i * BW] + 1e-9 * max_diag);
        }
        for i in 0..n {
            for d in (0..BW.min(i + 1)).rev() {
                let j = i - d;
                let mut sum = l[i * BW + d];
                for k in i.saturating_sub(BW - 1)..j {
                    sum -= l[i * BW + (i - k)] * l[j * BW + (j - k)];
                }
                if d == 0 {
                    if sum.is_nan() || sum <= 0.0 {
                        return Err(SplineError::Singular { coeff: i / 3 });
                    }
                    l[i * BW] = sum.sqrt();
                } else {
                    l[i * BW + d] = sum / l[j * BW];
                }
            }
        }
        let mut x = self.rhs.clone();
        for i in 0..n {
            for k in i.saturating_sub(BW - 1)..i {
                x[i] -= l[i * BW + (i - k)] * x[k];
            }
            x[i] /= l[i * BW];
        }
        for i in (0..n).rev() {
            for k in i + 1..(i + BW).min(n) {
                x[i] -= l[k * BW + (k - i)] * x[k];
            }
            x[i] /= l[i * BW];
        }
        Ok(x)
    }
}

/// Check the samples; the rotation matrices of the quaternions.
fn checked_rotations(
    times: &[f64],
    positions: &[V3],
    quaternions: &[[f64; 4]],
) -> Result<Vec<M3>, PoseSplineError> {
    let n = times.len();
    for (what, found) in [
        ("positions", positions.len()),
        ("quaternions", quaternions.len()),
    ] {
        if found != n {
            return Err(PoseSplineError::LengthMismatch {
                what,
                expected: n,
                found,
            });
        }
    }
    for (index, ((t, p), q)) in times.iter().zip(positions).zip(quaternions).enumerate() {
        let bad = |what| PoseSplineError::BadSample { index, what };
        if !t.is_finite() {
            return Err(bad("time"));
        }
        if !p.iter().all(|v| v.is_finite()) {
            return Err(bad("position"));
        }
        let norm2: f64 = q.iter().map(|v| v * v).sum();
        if !(norm2.is_finite() && norm2 > 1e-12) {
            return Err(bad("quaternion"));
        }
    }
    Ok(quaternions.iter().map(|&q| matrix_from_quat(q)).collect())
}

/// R_a·Exp(s·Log(R_aᵀ R_b)): the geodesic from R_a (s = 0) to R_b (s = 1).
fn slerp(ra: &M3, rb: &M3, s: f64) -> M3 {
    let d = log_so3(&mul_mm(&transpose(ra), rb));
    mul_mm(ra, &super::so3::exp_s(scale(d, s)))
}

/// Initial rotation control points: the samples' geodesic interpolation at
/// each control point's Greville abscissa (y_{k+1} + y_{k+2} + y_{k+3})/3.
fn initial_rotations(knots: &Knots, times: &[f64], rotations: &[M3]) -> Vec<M3> {
    let mut order: Vec<usize> = (0..times.len()).collect();
    order.sort_by(|&a, &b| times[a].total_cmp(&times[b]));
    let y = knots.knots();
    (0..knots.num_coeffs())
        .map(|k| {
            let g = y[k + 1..=k + DEGREE].iter().sum::<f64>() / DEGREE as f64;
            let hi = order
                .partition_point(|&s| times[s] < g)
                .min(order.len() - 1);
            let lo = hi.saturating_sub(1);
            let (a, b) = (order[lo], order[hi]);
            let span = times[b] - times[a];
            let s = if span > 0.0 {
                ((g - times[a]) / span).clamp(0.0, 1.0)
            } else {
                0.0
            };
            slerp(&rotations[a], &rotations[b], s)
        })
        .collect()
}

impl PoseSpline {
    /// The pose spline through pose samples: `positions[s]` (m) and the unit
    /// quaternion `quaternions[s]` = [w, x, y, z] (Hamilton, either sign) of
    /// B in W at `times[s]` (any order), on clamped cubic knots over
    /// [min t, max t] at most `knot_spacing` apart (MODEL.md §10).
    ///
    /// The spacing must keep the rotation between consecutive control points
    /// well below π (the differences d_j are principal logarithms), and every
    /// knot interval needs samples: a gap longer than about the spacing makes
    /// the position fit singular ([`SplineError::Singular`]).
    pub fn fit(
        times: &[f64],
        positions: &[V3],
        quaternions: &[[f64; 4]],
        knot_spacing: f64,
    ) -> Result<Self, PoseSplineError> {
        Ok(Self::fit_report(times, positions, quaternions, knot_spacing)?.0)
    }

    /// [`Self::fit`] and how it went.
    pub fn fit_report(
        times: &[f64],
        positions: &[V3],
        quaternions: &[[f64; 4]],
        knot_spacing: f64,
    ) -> Result<(Self, FitReport), PoseSplineError> {
        let rotations = checked_rotations(times, positions, quaternions)?;
        let t0 = times.iter().copied().fold(f64::INFINITY, f64::min);
        let t1 = times.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let knots = Knots::uniform(t0, t1, knot_spacing, DEGREE)?;
        let flat: Vec<f64> = positions.iter().flatten().copied().collect();
        let position = Spline::fit(knots.clone(), 3, times, &flat)?;
        let init = initial_rotations(&knots, times, &rotations);
        let mut spline = Self {
            position,
            rotation: init,
        };
        let (iterations, converged) = spline.refine_rotation(times, &rotations, MAX_ITERATIONS)?;
        let n = times.len() as f64;
        let mut sum = [0.0; 2];
        for (s, &t) in times.iter().enumerate() {
            let p = spline.position_rows(&spline.local(t)?)[0];
            let e_p = crate::geom::sub(p, positions[s]);
            let e_r = spline.rotation_error(t, &rotations[s])?;
            sum[0] += dot(e_p, e_p);
            sum[1] += dot(e_r, e_r);
        }
        let report = FitReport {
            iterations,
            converged,
            rms_position: (sum[0] / n).sqrt(),
            rms_rotation: (sum[1] / n).sqrt(),
        };
        Ok((spline, report))
    }

    /// e_r = Log(R̃ᵀ R(t)).
    fn rotation_error(&self, t: f64, r_meas: &M3) -> Result<V3, SplineError> {
        Ok(log_so3(&mul_mm(&transpose(r_meas), &self.rotation(t)?)))
    }

    /// Σ |e_r|² over the samples.
    fn rotation_cost(&self, times: &[f64], rotations: &[M3]) -> Result<f64, SplineError> {
        let mut cost = 0.0;
        for (&t, r) in times.iter().zip(rotations) {
            let e = self.rotation_error(t, r)?;
            cost += dot(e, e);
        }
        Ok(cost)
    }

    /// Refine the rotation control points to minimise Σ |Log(R̃_sᵀ R(t_s))|²
    /// over samples (t_s, R̃_s) by Levenberg–Marquardt in the local
    /// parameters R_k ← R_k·Exp(δ_k) (the damping vanishes as it converges,
    /// so it does not bias the minimum). Returns the iterations and whether
    /// it converged; control points no sample constrains keep their values.
    pub fn refine_rotation(
        &mut self,
        times: &[f64],
        rotations: &[M3],
        max_iterations: usize,
    ) -> Result<(usize, bool), SplineError> {
        if times.is_empty() {
            return Ok((0, true));
        }
        let m = self.num_control_points();
        let mut cost = self.rotation_cost(times, rotations)?;
        let mut lambda = 1e-6;
        for it in 0..max_iterations {
            let mut eq = Normal::zero(3 * m);
            for (&t, r) in times.iter().zip(rotations) {
                let res = self.pose_residual_r(t, [0.0; 3], r)?;
                eq.add(res.first, &res.e_r_rotation, &res.e_r);
            }
            loop {
                let step = eq.solve(lambda)?;
                let mut trial = self.clone();
                for k in 0..m {
                    trial.perturb(k, [0.0; 3], [step[3 * k], step[3 * k + 1], step[3 * k + 2]]);
                }
                let trial_cost = trial.rotation_cost(times, rotations)?;
                if trial_cost <= cost {
                    *self = trial;
                    cost = trial_cost;
                    lambda = (lambda * 0.1).max(1e-12);
                    let largest = step.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                    if largest < STEP_TOLERANCE || cost == 0.0 {
                        return Ok((it + 1, true));
                    }
                    break;
                }
                lambda *= 10.0;
                if lambda > 1e6 {
                    // no step lowers the cost: at its minimum to rounding
                    return Ok((it + 1, true));
                }
            }
        }
        Ok((max_iterations, false))
    }
}
