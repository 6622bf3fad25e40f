//! The least-squares spline through the joint samples (paper eq. (20), §5)
//! for the knot choice (docs/model.md §6.5), with the basis of every sample
//! kept for evaluating the fit there.
//!
//! The basis comes from the knots' span polynomials ([`SpanPolynomials`]: a
//! few Horner steps per sample instead of the Cox–de Boor table); the
//! normal equations, their banded Cholesky factorisation and the solves are
//! those of [`Spline::fit`], so the coefficients equal its to rounding
//! (tested).

use robimu_model::spline::MAX_DEGREE;
use robimu_model::{Basis, Knots, SpanPolynomials, Spline, SplineError, MAX_JOINTS};

/// The non-zero basis functions N_{first..first+p}(t) of one sample.
#[derive(Debug, Clone, Copy)]
struct SampleBasis {
    first: usize,
    values: [f64; MAX_DEGREE + 1],
}

/// A least-squares fit and the basis of its samples.
#[derive(Debug, Clone)]
pub struct JointFit {
    /// The fitted spline.
    pub spline: Spline,
    basis: Vec<SampleBasis>,
}

impl JointFit {
    /// Least-squares fit of `values[s·dim + j]` at `times[s]` (all in the
    /// knots' span): the problem of [`Spline::fit`], with its errors.
    pub fn new(
        knots: Knots,
        dim: usize,
        times: &[f64],
        values: &[f64],
    ) -> Result<Self, SplineError> {
        if !(1..=MAX_JOINTS).contains(&dim) {
            return Err(SplineError::BadDimension(dim));
        }
        if values.len() != times.len() * dim {
            return Err(SplineError::LengthMismatch {
                what: "sample values",
                expected: times.len() * dim,
                found: values.len(),
            });
        }
        let p = knots.degree();
        let m = knots.num_coeffs();
        let bw = p + 1;
        let spans = SpanPolynomials::new(&knots);
        let mut basis = Vec::with_capacity(times.len());
        // band[i·bw + d] = A[i][i−d]
        let mut band = vec![0.0; m * bw];
        let mut rhs = vec![0.0; m * dim];
        let mut b = Basis::default();
        for (s, &t) in times.iter().enumerate() {
            spans.basis(t, &mut b)?;
            let y = &values[s * dim..(s + 1) * dim];
            for a in 0..=p {
                let i = b.first + a;
                let na = b.d[0][a];
                for c in 0..=a {
                    band[i * bw + (a - c)] += na * b.d[0][c];
                }
                for j in 0..dim {
                    rhs[i * dim + j] += na * y[j];
                }
            }
            basis.push(SampleBasis {
                first: b.first,
                values: b.d[0],
            });
        }
        cholesky_solve(&mut band, &mut rhs, m, p, dim)?;
        Ok(Self {
            spline: Spline::new(knots, dim, rhs)?,
            basis,
        })
    }

    /// q at sample `s` of the fit (as [`Spline::evaluate_basis`] forms it).
    pub fn q_at(&self, s: usize) -> [f64; MAX_JOINTS] {
        let sb = &self.basis[s];
        let (dim, coeffs) = (self.spline.dim(), self.spline.coeffs());
        let count = self.spline.knots().degree() + 1;
        let mut q = [0.0; MAX_JOINTS];
        for a in 0..count {
            let w = sb.values[a];
            let c = &coeffs[(sb.first + a) * dim..(sb.first + a + 1) * dim];
            for j in 0..dim {
                q[j] += w * c[j];
            }
        }
        q
    }
}

/// Solve the banded normal equations (`band[i·bw + d]` = A[i][i−d], bw =
/// p + 1) for the right-hand sides `rhs` (m × dim) in place: banded
/// Cholesky A = L Lᵀ, then L y = rhs and Lᵀ c = y.
fn cholesky_solve(
    band: &mut [f64],
    rhs: &mut [f64],
    m: usize,
    p: usize,
    dim: usize,
) -> Result<(), SplineError> {
    let bw = p + 1;
    let scale = (0..m).map(|i| band[i * bw]).fold(0.0, f64::max);
    for i in 0..m {
        for d in (0..bw.min(i + 1)).rev() {
            let j = i - d;
            let mut sum = band[i * bw + d];
            // Σ_k L[i][k] L[j][k], k from max(i, j)−p … j−1
            let k0 = i.saturating_sub(p);
            for k in k0..j {
                sum -= band[i * bw + (i - k)] * band[j * bw + (j - k)];
            }
            if d == 0 {
                if sum.is_nan() || sum <= 1e-13 * scale {
                    return Err(SplineError::Singular { coeff: i });
                }
                band[i * bw] = sum.sqrt();
            } else {
                band[i * bw + d] = sum / band[j * bw];
            }
        }
    }
    for i in 0..m {
        for j in 0..dim {
            let mut v = rhs[i * dim + j];
            for k in i.saturating_sub(p)..i {
                v -= band[i * bw + (i - k)] * rhs[k * dim + j];
            }
            rhs[i * dim + j] = v / band[i * bw];
        }
    }
    for i in (0..m).rev() {
        for j in 0..dim {
            let mut v = rhs[i * dim + j];
            for k in i + 1..(i + bw).min(m) {
                v -= band[k * bw + (k - i)] * rhs[k * dim + j];
            }
            rhs[i * dim + j] = v / band[i * bw];
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use robimu_model::JointState;

    /// On noisy samples at random times, for degrees 1–5 and uniform and
    /// irregular knots, the coefficients equal [`Spline::fit`]'s to 1e-12
    /// relative and q at every sample [`Spline::evaluate`]'s; too few
    /// samples under a basis function and samples outside the span give
    /// its errors.
    #[test]
    fn equals_spline_fit() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(18);
        let irregular = Knots::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 0.3, 1.1, 1.2, 2.5, 4.0, 4.0, 4.0, 4.0],
        )
        .unwrap();
        let mut sets = vec![irregular];
        sets.extend((1..=5).map(|p| Knots::uniform(0.0, 4.0, 0.37, p).unwrap()));
        for knots in sets {
            let dim = 3;
            let mut times: Vec<f64> = (0..600).map(|_| rng.random_range(0.0..4.0)).collect();
            times.extend([0.0, 4.0]);
            times.sort_by(f64::total_cmp);
            let values: Vec<f64> = times
                .iter()
                .flat_map(|&t| [t.sin(), (2.0 * t).cos(), 0.1 * t * t])
                .map(|v| v + 1e-3 * rng.random_range(-1.0..1.0))
                .collect();
            let want = Spline::fit(knots.clone(), dim, &times, &values).unwrap();
            let got = JointFit::new(knots.clone(), dim, &times, &values).unwrap();
            let scale = want.coeffs().iter().fold(0.0f64, |m, c| m.max(c.abs()));
            for (a, b) in got.spline.coeffs().iter().zip(want.coeffs()) {
                assert!((a - b).abs() <= 1e-12 * scale, "{a} vs {b}");
            }
            let mut js = JointState::default();
            for (s, &t) in times.iter().enumerate() {
                want.evaluate(t, &mut js).unwrap();
                let q = got.q_at(s);
                for j in 0..dim {
                    assert!((q[j] - js.q[j]).abs() <= 1e-12 * scale, "t = {t}");
                }
            }
            let outside = [0.5, 4.5];
            assert_eq!(
                JointFit::new(knots.clone(), 1, &outside, &[0.0, 0.0]).unwrap_err(),
                Spline::fit(knots.clone(), 1, &outside, &[0.0, 0.0]).unwrap_err()
            );
        }
        let knots = Knots::uniform(0.0, 10.0, 1.0, 3).unwrap();
        let times = [0.0, 0.5, 1.0, 9.0, 10.0];
        let values = [0.0; 5];
        assert_eq!(
            JointFit::new(knots.clone(), 1, &times, &values).unwrap_err(),
            Spline::fit(knots, 1, &times, &values).unwrap_err()
        );
    }
}
