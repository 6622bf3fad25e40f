//! The least-squares spline through samples (paper eq. (20), §5; the
//! trajectory of docs/model.md §4.3 and its knot choice, §6.5): the banded
//! normal equations AᵀA c = Aᵀy of the basis at the sample times, solved by
//! banded Cholesky.
//!
//! The basis comes from the knots' span polynomials ([`SpanPolynomials`]:
//! p + 1 Horner steps of degree p per sample instead of the Cox–de Boor
//! table); the values equal [`Knots::basis`]'s to rounding (tested, and the
//! coefficients those of the Cox–de Boor fit to 1e-12).
//!
//! Many time-ordered samples are summed in two halves on two threads; the
//! rows of AᵀA and Aᵀy both halves reach (the p + 1 around the split) are
//! then summed again from the first half's sums over the second half's
//! samples in order, so the equations are those of one pass, bit for bit.

use super::{Knots, SpanPolynomials, Spline, SplineError, MAX_DEGREE};
use crate::MAX_JOINTS;

/// Values of the p + 1 non-zero basis functions at one t.
type Values = [f64; MAX_DEGREE + 1];

/// Samples from which the normal equations are summed on two threads.
const PARALLEL_SAMPLES: usize = 4096;

impl Spline {
    /// Least-squares fit to samples `values[s·dim + j]` at `times[s]` (all in
    /// [t0, t1]), by the banded normal equations (bandwidth p, Cholesky).
    pub fn fit(
        knots: Knots,
        dim: usize,
        times: &[f64],
        values: &[f64],
    ) -> Result<Self, SplineError> {
        Self::fit_on(&SpanPolynomials::new(&knots), dim, times, values)
    }

    /// [`Self::fit`] on the knots of `spans` (for a caller that evaluates
    /// the basis at the samples again).
    pub fn fit_on(
        spans: &SpanPolynomials,
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
        let mut eq = NormalEquations::of(spans, dim, times, values)?;
        eq.solve()?;
        Self::new(spans.knots().clone(), dim, eq.rhs)
    }
}

impl SpanPolynomials {
    /// The values of the p + 1 non-zero basis functions at t into
    /// `out[..p + 1]` (row 0 of [`Self::basis`], bit for bit); returns the
    /// index of the first.
    pub fn values(&self, t: f64, out: &mut Values) -> Result<usize, SplineError> {
        self.values_near(t, &mut 0, out)
    }

    /// [`Self::values`] with a guess of t's knot span: `span` (the previous
    /// t's, for times in order; searched for when wrong), set to t's.
    pub fn values_near(
        &self,
        t: f64,
        span: &mut usize,
        out: &mut Values,
    ) -> Result<usize, SplineError> {
        let (y, p) = (&self.knots.y, self.knots.degree);
        // y_μ ≤ t < y_{μ+1} with p ≤ μ < m is the span Knots::span finds
        let mu = match *span {
            mu if (p..y.len() - p - 1).contains(&mu) && y[mu] <= t && t < y[mu + 1] => mu,
            _ => self.knots.span(t)?,
        };
        *span = mu;
        let (s, c) = (t - self.knots.y[mu], &self.coef[mu - p][0]);
        match p {
            1 => horner_values::<1>(c, s, out),
            2 => horner_values::<2>(c, s, out),
            3 => horner_values::<3>(c, s, out),
            4 => horner_values::<4>(c, s, out),
            _ => horner_values::<5>(c, s, out),
        }
        Ok(mu - p)
    }
}

/// Row 0 of `super::horner`: the same operations.
#[inline(always)]
fn horner_values<const P: usize>(c: &[Values; MAX_DEGREE + 1], s: f64, out: &mut Values) {
    for a in 0..=P {
        let ca = &c[a];
        let mut v = ca[P];
        for i in (0..P).rev() {
            v = v * s + ca[i];
        }
        out[a] = v;
    }
}

/// AᵀA (banded: `band[i·bw + d]` = (AᵀA)[i][i−d], bw = p + 1) and Aᵀy
/// (`rhs[i·dim + j]`).
struct NormalEquations {
    p: usize,
    dim: usize,
    band: Vec<f64>,
    rhs: Vec<f64>,
}

impl NormalEquations {
    /// The equations of `times` and `values` (see the module doc).
    fn of(
        spans: &SpanPolynomials,
        dim: usize,
        times: &[f64],
        values: &[f64],
    ) -> Result<Self, SplineError> {
        let n = times.len();
        if n < PARALLEL_SAMPLES || !times.windows(2).all(|w| w[0] <= w[1]) {
            let mut eq = Self::zero(spans.knots(), dim);
            eq.add_samples(spans, times, values, 0..n)?;
            return Ok(eq);
        }
        let mid = n / 2;
        let sum = |range: std::ops::Range<usize>| {
            let mut eq = Self::zero(spans.knots(), dim);
            eq.add_samples(spans, times, values, range).map(|()| eq)
        };
        let (first, second) = crate::pair::join(|| sum(0..mid), || sum(mid..n));
        // the first half's error is the first sample's
        let (mut eq, second) = (first?, second?);
        let (bw, p) = (eq.p + 1, eq.p);
        // by time order the second half reaches no row below `lo`, the first
        // none above `hi`
        let mut v = Values::default();
        let lo = spans.values(times[mid], &mut v)?;
        let hi = spans.values(times[mid - 1], &mut v)? + p;
        eq.band[(hi + 1) * bw..].copy_from_slice(&second.band[(hi + 1) * bw..]);
        eq.rhs[(hi + 1) * dim..].copy_from_slice(&second.rhs[(hi + 1) * dim..]);
        // rows lo..=hi: the first half's sums go on over the second half's
        // samples that reach them (its first ones)
        for s in mid..n {
            let first = spans.values(times[s], &mut v)?;
            if first > hi {
                break;
            }
            debug_assert!(first >= lo);
            let rows = (hi - first).min(p) + 1;
            eq.add_rows(first, &v, &values[s * dim..(s + 1) * dim], rows);
        }
        Ok(eq)
    }

    /// Zero equations for `knots`.
    fn zero(knots: &Knots, dim: usize) -> Self {
        let (p, m) = (knots.degree(), knots.num_coeffs());
        Self {
            p,
            dim,
            band: vec![0.0; m * (p + 1)],
            rhs: vec![0.0; m * dim],
        }
    }

    /// Add the samples `range`, in order.
    fn add_samples(
        &mut self,
        spans: &SpanPolynomials,
        times: &[f64],
        values: &[f64],
        range: std::ops::Range<usize>,
    ) -> Result<(), SplineError> {
        match self.p {
            1 => self.add_samples_of::<1>(spans, times, values, range),
            2 => self.add_samples_of::<2>(spans, times, values, range),
            3 => self.add_samples_of::<3>(spans, times, values, range),
            4 => self.add_samples_of::<4>(spans, times, values, range),
            _ => self.add_samples_of::<5>(spans, times, values, range),
        }
    }

    /// [`Self::add_samples`] of degree P.
    fn add_samples_of<const P: usize>(
        &mut self,
        spans: &SpanPolynomials,
        times: &[f64],
        values: &[f64],
        range: std::ops::Range<usize>,
    ) -> Result<(), SplineError> {
        let (dim, mut v, mut span) = (self.dim, Values::default(), 0);
        for s in range {
            let first = spans.values_near(times[s], &mut span, &mut v)?;
            self.add::<P>(first, &v, &values[s * dim..(s + 1) * dim], P + 1);
        }
        Ok(())
    }

    /// Add one sample's terms (degree P: basis values `v` from `first`,
    /// values `y`) to its first `rows` rows.
    #[inline(always)]
    fn add<const P: usize>(&mut self, first: usize, v: &Values, y: &[f64], rows: usize) {
        let (bw, dim) = (P + 1, self.dim);
        let band = &mut self.band[first * bw..(first + rows) * bw];
        let rhs = &mut self.rhs[first * dim..(first + rows) * dim];
        let rows = band.chunks_exact_mut(bw).zip(rhs.chunks_exact_mut(dim));
        for (a, (row, r)) in rows.enumerate() {
            let na = v[a];
            for c in 0..=a {
                row[a - c] += na * v[c];
            }
            for (r, y) in r.iter_mut().zip(y) {
                *r += na * y;
            }
        }
    }

    /// [`Self::add`] of the degree of these equations.
    fn add_rows(&mut self, first: usize, v: &Values, y: &[f64], rows: usize) {
        match self.p {
            1 => self.add::<1>(first, v, y, rows),
            2 => self.add::<2>(first, v, y, rows),
            3 => self.add::<3>(first, v, y, rows),
            4 => self.add::<4>(first, v, y, rows),
            _ => self.add::<5>(first, v, y, rows),
        }
    }

    /// Solve in place (the coefficients into `rhs`): banded Cholesky
    /// AᵀA = L Lᵀ, then L z = Aᵀy and Lᵀ c = z.
    fn solve(&mut self) -> Result<(), SplineError> {
        let (p, dim) = (self.p, self.dim);
        let (band, rhs) = (&mut self.band, &mut self.rhs);
        let bw = p + 1;
        let m = band.len() / bw;
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::JointState;
    use crate::spline::Basis;

    /// The former fit: the Cox–de Boor basis ([`Knots::basis`]) at every
    /// sample, the same normal equations and solve.
    fn fit_cox_de_boor(
        knots: Knots,
        dim: usize,
        times: &[f64],
        values: &[f64],
    ) -> Result<Spline, SplineError> {
        let mut eq = NormalEquations::zero(&knots, dim);
        let mut b = Basis::default();
        for (s, &t) in times.iter().enumerate() {
            knots.basis(t, &mut b)?;
            let v: Values = std::array::from_fn(|a| b.d[0][a]);
            eq.add_rows(b.first, &v, &values[s * dim..(s + 1) * dim], b.count);
        }
        eq.solve()?;
        Spline::new(knots, dim, eq.rhs)
    }

    /// A small deterministic generator (no rand in this crate's tests).
    struct Lcg(u64);
    impl Lcg {
        fn uniform(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    fn knot_sets() -> Vec<Knots> {
        let irregular = Knots::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 0.3, 1.1, 1.2, 2.5, 4.0, 4.0, 4.0, 4.0],
        )
        .unwrap();
        let double = Knots::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 0.3, 1.1, 1.1, 2.5, 4.0, 4.0, 4.0, 4.0],
        )
        .unwrap();
        let mut sets = vec![irregular, double];
        sets.extend((1..=5).map(|p| Knots::uniform(0.0, 4.0, 0.37, p).unwrap()));
        sets
    }

    /// Noisy samples of three smooth curves at `count` random times in
    /// [0, 4] (and at both ends), sorted or not.
    fn samples(rng: &mut Lcg, count: usize, sorted: bool) -> (Vec<f64>, Vec<f64>) {
        let mut times: Vec<f64> = (0..count).map(|_| 4.0 * rng.uniform()).collect();
        times.extend([0.0, 4.0]);
        if sorted {
            times.sort_by(f64::total_cmp);
        }
        let values = times
            .iter()
            .flat_map(|&t| [t.sin(), (2.0 * t).cos(), 0.1 * t * t])
            .map(|v| v + 1e-3 * (2.0 * rng.uniform() - 1.0))
            .collect();
        (times, values)
    }

    /// The values equal row 0 of [`SpanPolynomials::basis`] bit for bit
    /// (and so [`Knots::basis`] to rounding, `span_polynomials_equal_cox_de_boor`),
    /// with a span guessed right or wrong.
    #[test]
    fn values_are_row_zero_of_the_basis() {
        let mut rng = Lcg(3);
        for knots in knot_sets() {
            let spans = SpanPolynomials::new(&knots);
            let (mut b, mut v, mut w) = (Basis::default(), Values::default(), Values::default());
            let mut ts: Vec<f64> = knots.knots().to_vec();
            ts.extend((0..500).map(|_| 4.0 * rng.uniform()));
            let mut sorted = ts.clone();
            sorted.sort_by(f64::total_cmp);
            let mut span = usize::MAX;
            for t in ts.into_iter().chain(sorted) {
                spans.basis(t, &mut b).unwrap();
                assert_eq!(spans.values(t, &mut v), Ok(b.first));
                assert_eq!(v[..b.count], b.d[0][..b.count], "t = {t}");
                assert_eq!(spans.values_near(t, &mut span, &mut w), Ok(b.first));
                assert_eq!((span - knots.degree(), w), (b.first, v), "t = {t}");
            }
            assert_eq!(
                spans.values(4.5, &mut v),
                Err(SplineError::OutOfRange {
                    t: 4.5,
                    t0: 0.0,
                    t1: 4.0
                })
            );
        }
    }

    /// On noisy samples at random times, for degrees 1–5 and uniform,
    /// irregular and double knots, few samples (one thread) and many (two,
    /// when time-ordered): the coefficients equal the Cox–de Boor fit's to
    /// 1e-12 relative and q at every sample its q; samples outside the span
    /// and too few samples under a basis function give its errors.
    #[test]
    fn equals_the_cox_de_boor_fit() {
        let mut rng = Lcg(18);
        for knots in knot_sets() {
            for (count, sorted) in [(600, true), (9000, true), (9000, false)] {
                let dim = 3;
                let (times, values) = samples(&mut rng, count, sorted);
                let want = fit_cox_de_boor(knots.clone(), dim, &times, &values).unwrap();
                let got = Spline::fit(knots.clone(), dim, &times, &values).unwrap();
                let scale = want.coeffs().iter().fold(0.0f64, |m, c| m.max(c.abs()));
                for (a, b) in got.coeffs().iter().zip(want.coeffs()) {
                    assert!((a - b).abs() <= 1e-12 * scale, "{a} vs {b}");
                }
                let (mut js, mut jg) = (JointState::default(), JointState::default());
                for &t in times.iter().step_by(7) {
                    want.evaluate(t, &mut js).unwrap();
                    got.evaluate(t, &mut jg).unwrap();
                    for j in 0..dim {
                        assert!((jg.q[j] - js.q[j]).abs() <= 1e-12 * scale, "t = {t}");
                    }
                }
            }
            for outside in [vec![0.5, 4.5], {
                let mut t: Vec<f64> = (0..5000).map(|k| k as f64 * 1e-3).collect();
                t.push(4.5);
                t
            }] {
                let zeros = vec![0.0; outside.len()];
                assert_eq!(
                    Spline::fit(knots.clone(), 1, &outside, &zeros).unwrap_err(),
                    fit_cox_de_boor(knots.clone(), 1, &outside, &zeros).unwrap_err()
                );
            }
        }
        let knots = Knots::uniform(0.0, 10.0, 1.0, 3).unwrap();
        let mut times = vec![0.0, 0.5, 1.0, 9.0, 10.0];
        for _ in 0..2 {
            let values = vec![0.0; times.len()];
            assert_eq!(
                Spline::fit(knots.clone(), 1, &times, &values).unwrap_err(),
                fit_cox_de_boor(knots.clone(), 1, &times, &values).unwrap_err()
            );
            // many samples, none under the middle basis functions
            times = (0..4000).map(|k| k as f64 * 1e-3).collect();
            times.extend((0..6000).map(|k| 9.0 + k as f64 * 1e-4));
        }
    }

    /// The two-thread sum is the one-thread sum bit for bit, for degrees
    /// 1–5 on uniform, irregular and double knots: time-ordered samples with
    /// the split inside a span, at a knot with repeated times, and across a
    /// gap of several spans.
    #[test]
    fn two_halves_sum_as_one_pass() {
        let mut rng = Lcg(5);
        let n = 9000;
        assert!(n >= PARALLEL_SAMPLES);
        for knots in knot_sets() {
            let spans = SpanPolynomials::new(&knots);
            let uniform: Vec<f64> = (0..n).map(|k| 4.0 * k as f64 / (n - 1) as f64).collect();
            // the interior knot nearest 2 s at the split's two samples
            let knot = *knots
                .knots()
                .iter()
                .min_by(|a, b| (*a - 2.0).abs().total_cmp(&(*b - 2.0).abs()))
                .unwrap();
            let half = (n / 2 - 1) as f64;
            let mut at_knot: Vec<f64> = (0..n / 2).map(|k| knot * k as f64 / half).collect();
            at_knot.extend((0..n / 2).map(|k| knot + (4.0 - knot) * k as f64 / half));
            assert_eq!((at_knot[n / 2 - 1], at_knot[n / 2]), (knot, knot));
            let mut gap: Vec<f64> = (0..n / 2).map(|k| k as f64 * 2e-4).collect();
            gap.extend((0..n / 2).map(|k| 3.0 + k as f64 * 2e-4));
            for times in [uniform, at_knot, gap] {
                let dim = 2;
                let values: Vec<f64> = times
                    .iter()
                    .flat_map(|&t| [(3.0 * t).sin(), t.cos() + rng.uniform()])
                    .collect();
                let two = NormalEquations::of(&spans, dim, &times, &values).unwrap();
                let mut one = NormalEquations::zero(&knots, dim);
                one.add_samples(&spans, &times, &values, 0..times.len())
                    .unwrap();
                assert_eq!(two.band, one.band, "p = {}", knots.degree());
                assert_eq!(two.rhs, one.rhs, "p = {}", knots.degree());
            }
        }
    }
}
