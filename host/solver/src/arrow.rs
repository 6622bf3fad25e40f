//! The normal matrix of the calibration problem and its factorisation.
//!
//! Ordering the unknowns as θ = [c, x] — the spline coefficients c first,
//! basis function by basis function, then the model parameters x — makes the
//! Gauss–Newton matrix an *arrowhead*:
//!
//! ```text
//!     A = [ A_cc  A_cx ]     A_cc: banded (every residual touches p+1
//!         [ A_xc  A_xx ]           consecutive basis functions), nc × nc
//!                            A_cx: dense border, nc × nx
//!                            A_xx: dense corner, nx × nx
//! ```
//!
//! It is factored as a banded Cholesky L Lᵀ = A_cc, the border W = L⁻¹ A_cx,
//! and the dense Cholesky of the Schur complement S = A_xx − Wᵀ W
//! (the information about x with c marginalised out). S⁻¹ is the marginal
//! covariance of x, the paper's (24). Cost: O(nc·w² + nc·w·nx + nc·nx²).
//!
//! Storage of the band: row `i` keeps columns `i−w ..= i` in ascending order at
//! `band[i·(w+1) ..]`, the diagonal last; entries with negative column index are
//! padding and stay zero.

mod inverse;

use faer::linalg::solvers::{DenseSolveCore, Llt, Solve};
use faer::{Mat, MatRef, Side};

pub use inverse::SelectedInverse;

/// A symmetric arrowhead matrix (see the module doc). Only the lower band,
/// the border and the full corner are stored.
#[derive(Debug, Clone)]
pub struct ArrowMatrix {
    nc: usize,
    w: usize,
    nx: usize,
    band: Vec<f64>,
    border: Vec<f64>,
    corner: Mat<f64>,
}

/// Failure of a factorisation: the matrix is not numerically positive definite.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FactorError {
    /// A pivot of the banded part was not positive.
    #[error(
        "the trajectory block of the normal matrix is not positive definite at column {column}"
    )]
    BandNotPositiveDefinite {
        /// The spline-coefficient column.
        column: usize,
    },
    /// The Schur complement (information about x) is not positive definite.
    #[error("the information about the model parameters is not positive definite")]
    SchurNotPositiveDefinite,
}

impl ArrowMatrix {
    /// A zero matrix with `nc` band unknowns of half-bandwidth `w` and `nx`
    /// border unknowns.
    pub fn zeros(nc: usize, w: usize, nx: usize) -> Self {
        Self {
            nc,
            w,
            nx,
            band: vec![0.0; nc * (w + 1)],
            border: vec![0.0; nc * nx],
            corner: Mat::zeros(nx, nx),
        }
    }

    /// Band size, half-bandwidth and border size.
    pub fn dims(&self) -> (usize, usize, usize) {
        (self.nc, self.w, self.nx)
    }

    /// Set every entry to zero, keeping the storage.
    pub fn clear(&mut self) {
        self.band.fill(0.0);
        self.border.fill(0.0);
        self.corner.fill(0.0);
    }

    #[inline]
    fn band_index(&self, i: usize, j: usize) -> usize {
        debug_assert!(j <= i && i - j <= self.w && i < self.nc);
        i * (self.w + 1) + (j + self.w - i)
    }

    /// Entry (i, j) of A, for any i, j (zero outside the stored pattern).
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let (nc, w) = (self.nc, self.w);
        match (i < nc, j < nc) {
            (true, true) => {
                let (i, j) = if i >= j { (i, j) } else { (j, i) };
                if i - j > w {
                    0.0
                } else {
                    self.band[self.band_index(i, j)]
                }
            }
            (true, false) => self.border[i * self.nx + (j - nc)],
            (false, true) => self.border[j * self.nx + (i - nc)],
            (false, false) => self.corner[(i - nc, j - nc)],
        }
    }

    /// Add a dense symmetric block `local` whose rows/columns are the band
    /// unknowns `c0 .. c0 + nl` followed by the border unknowns `x_index`
    /// (indices into x). Only the lower triangle of `local` is read.
    ///
    /// # Panics
    /// If the band unknowns leave the band (`nl > w + 1`) or the matrix, or if
    /// `local` is not `(nl + x_index.len())` square.
    #[track_caller]
    pub fn add_local(&mut self, c0: usize, nl: usize, x_index: &[usize], local: MatRef<'_, f64>) {
        let nb = x_index.len();
        assert!(
            nl <= self.w + 1 && c0 + nl <= self.nc,
            "band block out of range"
        );
        assert!(
            local.nrows() == nl + nb && local.ncols() == nl + nb,
            "local block shape"
        );
        for a in 0..nl {
            let i = c0 + a;
            for b in 0..=a {
                let k = self.band_index(i, c0 + b);
                self.band[k] += local[(a, b)];
            }
            for (b, &xb) in x_index.iter().enumerate() {
                self.border[i * self.nx + xb] += local[(nl + b, a)];
            }
        }
        for (a, &xa) in x_index.iter().enumerate() {
            for (b, &xb) in x_index.iter().enumerate().take(a + 1) {
                let v = local[(nl + a, nl + b)];
                self.corner[(xa, xb)] += v;
                if xa != xb {
                    self.corner[(xb, xa)] += v;
                }
            }
        }
    }

    /// Add `v` to the band entry (i, j), `j ≤ i ≤ j + w` (and so to (j, i)).
    ///
    /// # Panics
    /// In debug builds, if (i, j) is outside the stored band.
    #[inline]
    pub fn add_cc(&mut self, i: usize, j: usize, v: f64) {
        let k = self.band_index(i, j);
        self.band[k] += v;
    }

    /// Add every entry of `other` (same dimensions) to `self`.
    ///
    /// # Panics
    /// If the dimensions differ.
    #[track_caller]
    pub fn add_assign(&mut self, other: &ArrowMatrix) {
        assert_eq!(self.dims(), other.dims());
        for (a, b) in self.band.iter_mut().zip(&other.band) {
            *a += b;
        }
        for (a, b) in self.border.iter_mut().zip(&other.border) {
            *a += b;
        }
        self.corner += &other.corner;
    }

    /// Add the band of `other` — same band size, half-bandwidth at most
    /// this one's, any border — to this band.
    ///
    /// # Panics
    /// If the band sizes differ or `other`'s band is wider.
    #[track_caller]
    pub fn add_band(&mut self, other: &ArrowMatrix) {
        assert!(
            other.nc == self.nc && other.w <= self.w,
            "band of another shape"
        );
        let (w, wo) = (self.w, other.w);
        for i in 0..self.nc {
            let d = wo.min(i);
            let dst = i * (w + 1) + w - d;
            let src = i * (wo + 1) + wo - d;
            for (a, b) in self.band[dst..=dst + d]
                .iter_mut()
                .zip(&other.band[src..=src + d])
            {
                *a += b;
            }
        }
    }

    /// The matrix of the band unknowns and the border unknowns `keep` only
    /// (in that order): the normal matrix of the problem without the other
    /// border unknowns (they held fixed), e.g. one candidate's block of a
    /// linearisation with several.
    ///
    /// # Panics
    /// If an index of `keep` is not a border unknown.
    #[track_caller]
    pub fn restrict_border(&self, keep: &[usize]) -> ArrowMatrix {
        assert!(
            keep.iter().all(|&k| k < self.nx),
            "border index out of range"
        );
        let nk = keep.len();
        let mut border = vec![0.0; self.nc * nk];
        for (dst, src) in border
            .chunks_exact_mut(nk.max(1))
            .zip(self.border.chunks_exact(self.nx.max(1)))
        {
            for (d, &k) in dst.iter_mut().zip(keep) {
                *d = src[k];
            }
        }
        ArrowMatrix {
            nc: self.nc,
            w: self.w,
            nx: nk,
            band: self.band.clone(),
            border,
            corner: Mat::from_fn(nk, nk, |i, j| self.corner[(keep[i], keep[j])]),
        }
    }

    /// Add `v` to the corner entry (k, l) and, when k ≠ l, to (l, k).
    pub fn add_xx(&mut self, k: usize, l: usize, v: f64) {
        self.corner[(k, l)] += v;
        if k != l {
            self.corner[(l, k)] += v;
        }
    }

    /// The diagonal of A.
    pub fn diagonal(&self) -> Vec<f64> {
        let mut d: Vec<f64> = (0..self.nc)
            .map(|i| self.band[self.band_index(i, i)])
            .collect();
        d.extend((0..self.nx).map(|k| self.corner[(k, k)]));
        d
    }

    /// Add `d[i]` to the diagonal entry i (Levenberg–Marquardt damping).
    ///
    /// # Panics
    /// If `d.len()` is not `nc + nx`.
    #[track_caller]
    pub fn add_diagonal(&mut self, d: &[f64]) {
        assert_eq!(d.len(), self.nc + self.nx);
        for i in 0..self.nc {
            let k = self.band_index(i, i);
            self.band[k] += d[i];
        }
        for k in 0..self.nx {
            self.corner[(k, k)] += d[self.nc + k];
        }
    }

    /// The marginal information about x: S = A_xx − A_xc A_cc⁻¹ A_cx.
    pub fn schur_complement(&self) -> Result<Mat<f64>, FactorError> {
        let (l, w) = self.factor_parts()?;
        Ok(self.schur_from(&l, &w))
    }

    /// Factor A (see the module doc).
    pub fn factor(&self) -> Result<ArrowFactor, FactorError> {
        let (l, w) = self.factor_parts()?;
        let s = self.schur_from(&l, &w);
        let llt = s
            .llt(Side::Lower)
            .map_err(|_| FactorError::SchurNotPositiveDefinite)?;
        Ok(ArrowFactor {
            nc: self.nc,
            bw: self.w,
            nx: self.nx,
            l,
            w,
            s,
            llt,
        })
    }

    /// Banded Cholesky of A_cc and W = L⁻¹ A_cx.
    fn factor_parts(&self) -> Result<(Vec<f64>, Vec<f64>), FactorError> {
        let (nc, bw, nx) = (self.nc, self.w, self.nx);
        let r = bw + 1;
        let mut l = self.band.clone();
        for i in 0..nc {
            let j0 = i.saturating_sub(bw);
            for j in j0..=i {
                // L[i][j] = (A[i][j] − Σ_{k=max(i,j)-w}^{j-1} L[i][k] L[j][k]) / L[j][j]
                let k0 = i.saturating_sub(bw);
                let ri = i * r + bw - i; // + k gives L[i][k]
                let rj = j * r + bw - j;
                let s = l[i * r + (j + bw - i)] - dot(&l[ri + k0..ri + j], &l[rj + k0..rj + j]);
                if j == i {
                    if s.is_nan() || s <= 0.0 || s.is_infinite() {
                        return Err(FactorError::BandNotPositiveDefinite { column: i });
                    }
                    l[i * r + bw] = s.sqrt();
                } else {
                    l[i * r + (j + bw - i)] = s / l[j * r + bw];
                }
            }
        }
        // Forward substitution, row by row, all nx columns at once.
        let mut w = self.border.clone();
        for i in 0..nc {
            let (done, rest) = w.split_at_mut(i * nx);
            let row = &mut rest[..nx];
            for k in i.saturating_sub(bw)..i {
                let lik = l[i * r + (k + bw - i)];
                if lik != 0.0 {
                    let wk = &done[k * nx..(k + 1) * nx];
                    for (a, b) in row.iter_mut().zip(wk) {
                        *a -= lik * b;
                    }
                }
            }
            let d = l[i * r + bw];
            for a in row.iter_mut() {
                *a /= d;
            }
        }
        Ok((l, w))
    }

    fn schur_from(&self, _l: &[f64], w: &[f64]) -> Mat<f64> {
        let (nc, nx) = (self.nc, self.nx);
        let wm = MatRef::from_row_major_slice(w, nc, nx);
        let mut s = self.corner.clone();
        faer::linalg::matmul::matmul(
            s.as_mut(),
            faer::Accum::Add,
            wm.transpose(),
            wm,
            -1.0,
            faer::Par::Seq,
        );
        s
    }
}

/// Σ a_k b_k in four interleaved partial sums (the band factorisation's
/// and solve's inner products: one running sum would wait on the previous
/// addition at every term, four keep the floating-point unit busy; the
/// rounding differs from the sum in order, not its accuracy).
#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    debug_assert_eq!(a.len(), b.len());
    let mut acc = [0.0; 4];
    let (qa, qb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (qa.remainder(), qb.remainder());
    for (x, y) in qa.zip(qb) {
        for l in 0..4 {
            acc[l] += x[l] * y[l];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

/// A factored [`ArrowMatrix`].
#[derive(Debug)]
pub struct ArrowFactor {
    nc: usize,
    bw: usize,
    nx: usize,
    l: Vec<f64>,
    w: Vec<f64>,
    s: Mat<f64>,
    llt: Llt<f64>,
}

impl ArrowFactor {
    /// Solve A δ = rhs in place (`rhs.len() == nc + nx`).
    ///
    /// # Panics
    /// If `rhs` has the wrong length.
    #[track_caller]
    pub fn solve_in_place(&self, rhs: &mut [f64]) {
        let (nc, bw, nx) = (self.nc, self.bw, self.nx);
        assert_eq!(rhs.len(), nc + nx);
        let r = bw + 1;
        let (rc, rx) = rhs.split_at_mut(nc);
        // L y_c = r_c
        for i in 0..nc {
            let k0 = i.saturating_sub(bw);
            let li = &self.l[i * r + (k0 + bw - i)..i * r + bw];
            rc[i] = (rc[i] - dot(li, &rc[k0..i])) / self.l[i * r + bw];
        }
        // S δx = r_x − Wᵀ y_c
        for i in 0..nc {
            let yi = rc[i];
            if yi != 0.0 {
                for (a, b) in rx.iter_mut().zip(&self.w[i * nx..(i + 1) * nx]) {
                    *a -= b * yi;
                }
            }
        }
        let mut col = faer::Mat::from_fn(nx, 1, |i, _| rx[i]);
        self.llt.solve_in_place(col.as_mut());
        for (i, v) in rx.iter_mut().enumerate() {
            *v = col[(i, 0)];
        }
        // Lᵀ δc = y_c − W δx
        for i in 0..nc {
            let wi = &self.w[i * nx..(i + 1) * nx];
            rc[i] -= wi.iter().zip(rx.iter()).map(|(a, b)| a * b).sum::<f64>();
        }
        for i in (0..nc).rev() {
            let v = rc[i] / self.l[i * r + bw];
            rc[i] = v;
            for k in i.saturating_sub(bw)..i {
                rc[k] -= self.l[i * r + (k + bw - i)] * v;
            }
        }
    }

    /// The Schur complement S (information about x, c marginalised out).
    pub fn schur(&self) -> MatRef<'_, f64> {
        self.s.as_ref()
    }

    /// S⁻¹: the marginal covariance of x (the paper's (24)).
    pub fn covariance_x(&self) -> Mat<f64> {
        self.llt.inverse()
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// Every entry of a restricted matrix is the original's at the kept
    /// border unknowns (read through `get`, the full-matrix view).
    #[test]
    fn restrict_border_keeps_the_chosen_unknowns() {
        let (nc, w, nx) = (7, 2, 4);
        let mut a = ArrowMatrix::zeros(nc, w, nx);
        let v = |i: usize, j: usize| 1.0 + (3 * i + 7 * j) as f64 * 0.01;
        for i in 0..nc {
            for j in i.saturating_sub(w)..=i {
                a.add_cc(i, j, v(i, j));
            }
        }
        let local = Mat::from_fn(1 + nx, 1 + nx, |i, j| v(i + 20, j + 20) + v(j + 20, i + 20));
        a.add_local(3, 1, &[0, 1, 2, 3], local.as_ref());
        let keep = [3, 1];
        let r = a.restrict_border(&keep);
        assert_eq!(r.dims(), (nc, w, 2));
        let full = |i: usize| if i < nc { i } else { nc + keep[i - nc] };
        for i in 0..nc + 2 {
            for j in 0..nc + 2 {
                assert_eq!(r.get(i, j), a.get(full(i), full(j)), "({i}, {j})");
            }
        }
    }

    /// A random SPD arrowhead built from random local blocks, as assembly does.
    pub(super) fn random_arrow(nc: usize, w: usize, nx: usize, seed: u64) -> ArrowMatrix {
        let mut state = seed;
        let mut rnd = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let mut a = ArrowMatrix::zeros(nc, w, nx);
        let nl = w + 1;
        let xs: Vec<usize> = (0..nx).collect();
        for c0 in 0..=(nc - nl) {
            // local = JᵀJ of a random 2·(nl+nx) × (nl+nx) Jacobian
            let m = nl + nx;
            let j = Mat::from_fn(2 * m, m, |_, _| rnd());
            let local = j.transpose() * &j;
            a.add_local(c0, nl, &xs, local.as_ref());
        }
        a
    }

    pub(super) fn dense(a: &ArrowMatrix) -> Mat<f64> {
        let n = a.nc + a.nx;
        Mat::from_fn(n, n, |i, j| a.get(i, j))
    }

    #[test]
    fn solve_matches_dense_cholesky() {
        for &(nc, w, nx, seed) in &[(30, 3, 5, 1), (50, 7, 0, 2), (12, 11, 4, 3), (40, 5, 9, 4)] {
            let a = random_arrow(nc, w, nx, seed);
            let d = dense(&a);
            let f = a.factor().unwrap();
            let rhs: Vec<f64> = (0..nc + nx).map(|i| (i as f64 * 0.37).sin()).collect();
            let mut x = rhs.clone();
            f.solve_in_place(&mut x);
            // residual of the solve, against the dense matrix
            let xm = Mat::from_fn(nc + nx, 1, |i, _| x[i]);
            let r = &d * &xm;
            for i in 0..nc + nx {
                assert!(
                    (r[(i, 0)] - rhs[i]).abs() < 1e-9 * (1.0 + rhs[i].abs()),
                    "row {i}"
                );
            }
            // and against faer's dense solver
            let reference = d
                .llt(Side::Lower)
                .unwrap()
                .solve(Mat::from_fn(nc + nx, 1, |i, _| rhs[i]));
            for i in 0..nc + nx {
                assert!((reference[(i, 0)] - x[i]).abs() < 1e-9 * (1.0 + x[i].abs()));
            }
            if nx > 0 {
                // covariance of x = the x-block of the dense inverse
                let inv = d.llt(Side::Lower).unwrap().inverse();
                let cov = f.covariance_x();
                for i in 0..nx {
                    for j in 0..nx {
                        let e = inv[(nc + i, nc + j)];
                        assert!((cov[(i, j)] - e).abs() < 1e-9 * (1.0 + e.abs()));
                    }
                }
            }
        }
    }

    /// With no band (nc = 0) the matrix is its dense corner: the factor is
    /// its Cholesky factorisation, the covariance its inverse (the dense
    /// problems of [`crate::dense`]).
    #[test]
    fn no_band_is_the_dense_corner() {
        let nx = 4;
        let mut a = ArrowMatrix::zeros(0, 0, nx);
        assert_eq!(a.dims(), (0, 0, nx));
        let m = Mat::from_fn(nx, nx, |i, j| {
            let (i, j) = (i as f64, j as f64);
            (0.3 * (i + j)).cos() + if i == j { 3.0 } else { 0.0 }
        });
        for i in 0..nx {
            for j in 0..=i {
                a.add_xx(i, j, m[(i, j)]);
            }
        }
        assert_eq!(dense(&a), m);
        assert_eq!(a.diagonal().len(), nx);
        let f = a.factor().unwrap();
        assert_eq!(f.schur(), m.as_ref());
        let rhs = [1.0, -2.0, 0.5, 3.0];
        let mut x = rhs.to_vec();
        f.solve_in_place(&mut x);
        let inv = m.llt(Side::Lower).unwrap().inverse();
        let cov = f.covariance_x();
        for i in 0..nx {
            let want: f64 = (0..nx).map(|j| inv[(i, j)] * rhs[j]).sum();
            assert!((x[i] - want).abs() < 1e-12, "{i}");
            for j in 0..nx {
                assert!((cov[(i, j)] - inv[(i, j)]).abs() < 1e-12);
            }
        }
        let mut singular = ArrowMatrix::zeros(0, 0, 2);
        singular.add_xx(0, 0, 1.0);
        assert_eq!(
            singular.factor().unwrap_err(),
            FactorError::SchurNotPositiveDefinite
        );
    }

    #[test]
    fn damping_and_diagonal() {
        let mut a = random_arrow(10, 2, 3, 9);
        let before = a.diagonal();
        a.add_diagonal(&[1.5; 13]);
        let after = a.diagonal();
        for (b, c) in before.iter().zip(&after) {
            assert!((c - b - 1.5).abs() < 1e-12);
        }
    }

    /// A narrower band added entry by entry: every entry of the sum is the
    /// sum of the entries (the border and corner untouched).
    #[test]
    fn add_band_adds_a_narrower_band() {
        let mut a = random_arrow(10, 4, 3, 5);
        let before = a.clone();
        let b = random_arrow(10, 2, 0, 6);
        a.add_band(&b);
        for i in 0..13 {
            for j in 0..13 {
                let want = before.get(i, j) + if i < 10 && j < 10 { b.get(i, j) } else { 0.0 };
                assert_eq!(a.get(i, j), want, "({i}, {j})");
            }
        }
        assert!(b.get(5, 2) == 0.0 && b.get(5, 3) != 0.0);
    }

    #[test]
    fn indefinite_band_is_reported_with_its_column() {
        let mut a = ArrowMatrix::zeros(4, 1, 1);
        let mut d = vec![1.0; 5];
        d[2] = -1.0;
        a.add_diagonal(&d);
        assert_eq!(
            a.factor().unwrap_err(),
            FactorError::BandNotPositiveDefinite { column: 2 }
        );
        let mut b = ArrowMatrix::zeros(3, 1, 2);
        b.add_diagonal(&[1.0, 1.0, 1.0, 1.0, 0.0]);
        assert_eq!(
            b.factor().unwrap_err(),
            FactorError::SchurNotPositiveDefinite
        );
    }
}
