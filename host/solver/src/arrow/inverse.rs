//! Selected inversion of a factored [`ArrowMatrix`](super::ArrowMatrix):
//! the entries of A⁻¹ on the band's pattern (|i − j| ≤ w among the band
//! unknowns), the whole border block and the corner, without forming A⁻¹.
//! They are what a leverage (tr of a local Gram against A⁻¹) or a
//! marginal covariance of a few band unknowns needs.
//!
//! With A_cc = L Lᵀ, W = L⁻¹ A_cx and S the Schur complement (module doc of
//! [`super`]), Z = A_cc⁻¹ A_cx = L⁻ᵀ W and Y = Z S⁻¹:
//!
//! ```text
//! A⁻¹ = [ Σ + Y Zᵀ   −Y  ]      Σ = A_cc⁻¹
//!       [   −Yᵀ      S⁻¹ ]
//! ```
//!
//! Σ on the band comes from Lᵀ Σ = L⁻¹ (Takahashi's recursion): for
//! j ≥ i, Σ_ij = (δ_ij / l_ii − Σ_{k=i+1}^{i+w} l_ki Σ_kj) / l_ii, rows from
//! the last up; every Σ_kj it reads has |k − j| ≤ w and k > i, so the band
//! is closed under the recursion. Cost O(nc·w² + nc·w·nx + nc·nx²), the
//! factorisation's.

use faer::{Mat, MatRef};

use super::{dot, ArrowFactor};

/// The entries of A⁻¹ on the arrowhead's pattern ([`ArrowFactor::selected_inverse`]).
#[derive(Debug, Clone)]
pub struct SelectedInverse {
    nc: usize,
    bw: usize,
    nx: usize,
    /// (A⁻¹)_cc on the band, in [`ArrowMatrix`](super::ArrowMatrix)'s band layout.
    band: Vec<f64>,
    /// (A⁻¹)_cx, nc × nx row-major.
    cross: Vec<f64>,
    /// (A⁻¹)_xx = S⁻¹.
    corner: Mat<f64>,
}

impl ArrowFactor {
    /// The entries of A⁻¹ on the arrowhead's pattern (module doc).
    pub fn selected_inverse(&self) -> SelectedInverse {
        let (nc, bw, nx) = (self.nc, self.bw, self.nx);
        let r = bw + 1;
        let l = |i: usize, j: usize| self.l[i * r + (j + bw - i)]; // i ≥ j
                                                                   // Σ = A_cc⁻¹ on the band, rows from the last up
        let mut band = vec![0.0; nc * r];
        let at = |i: usize, j: usize| {
            if i >= j {
                i * r + (j + bw - i)
            } else {
                j * r + (i + bw - j)
            }
        };
        let (mut col, mut lk) = (vec![0.0; r], vec![0.0; r]);
        for i in (0..nc).rev() {
            let kmax = (i + bw).min(nc - 1);
            let lii = l(i, i);
            for (c, k) in lk.iter_mut().zip(i + 1..=kmax) {
                *c = l(k, i);
            }
            for j in (i..=kmax).rev() {
                // Σ_{k=i+1..=kmax} l_ki Σ_kj
                for (c, k) in col.iter_mut().zip(i + 1..=kmax) {
                    *c = band[at(k, j)];
                }
                let s = dot(&lk[..kmax - i], &col[..kmax - i]);
                let delta = if j == i { 1.0 / lii } else { 0.0 };
                band[at(j, i)] = (delta - s) / lii;
            }
        }
        // Z = L⁻ᵀ W (backward substitution), Y = Z S⁻¹
        let mut z = self.w.clone();
        for i in (0..nc).rev() {
            let (head, tail) = z.split_at_mut((i + 1) * nx);
            let zi = &mut head[i * nx..];
            for k in i + 1..=(i + bw).min(nc.saturating_sub(1)) {
                let lki = l(k, i);
                let zk = &tail[(k - i - 1) * nx..(k - i) * nx];
                for (a, b) in zi.iter_mut().zip(zk) {
                    *a -= lki * b;
                }
            }
            let d = l(i, i);
            for a in zi.iter_mut() {
                *a /= d;
            }
        }
        let corner = self.covariance_x();
        let zm = MatRef::from_row_major_slice(&z, nc, nx);
        let ym = zm * &corner;
        let y: Vec<f64> = (0..nc * nx)
            .map(|e| ym[(e / nx.max(1), e % nx.max(1))])
            .collect();
        // band of Y Zᵀ
        for i in 0..nc {
            let yi = &y[i * nx..(i + 1) * nx];
            for j in i.saturating_sub(bw)..=i {
                band[i * r + (j + bw - i)] += dot(yi, &z[j * nx..(j + 1) * nx]);
            }
        }
        let cross = y.iter().map(|v| -v).collect();
        SelectedInverse {
            nc,
            bw,
            nx,
            band,
            cross,
            corner,
        }
    }
}

impl SelectedInverse {
    /// (A⁻¹)_ij, or `None` off the pattern (two band unknowns more than w
    /// apart, or an index out of range).
    pub fn get(&self, i: usize, j: usize) -> Option<f64> {
        let (nc, bw, nx) = (self.nc, self.bw, self.nx);
        let n = nc + nx;
        if i >= n || j >= n {
            return None;
        }
        let (i, j) = if i >= j { (i, j) } else { (j, i) };
        if j >= nc {
            Some(self.corner[(i - nc, j - nc)])
        } else if i >= nc {
            Some(self.cross[j * nx + (i - nc)])
        } else if i - j <= bw {
            Some(self.band[i * (bw + 1) + (j + bw - i)])
        } else {
            None
        }
    }

    /// tr(A⁻¹[idx, idx] · G) = Σ_ab (A⁻¹)_{idx_a idx_b} G_ab for a local
    /// symmetric block G over the unknowns `idx` (the leverage of rows
    /// whose Gram matrix is G); `None` if a pair of `idx` is off the pattern.
    pub fn trace_product(&self, idx: &[usize], g: MatRef<'_, f64>) -> Option<f64> {
        if g.nrows() != idx.len() || g.ncols() != idx.len() {
            return None;
        }
        let mut t = 0.0;
        for (a, &i) in idx.iter().enumerate() {
            for (b, &j) in idx.iter().enumerate() {
                t += self.get(i, j)? * g[(a, b)];
            }
        }
        Some(t)
    }
}

#[cfg(test)]
mod tests {
    use faer::linalg::solvers::DenseSolveCore;
    use faer::{Mat, Side};

    use super::super::tests::{dense, random_arrow};

    /// Every entry on the pattern equals the dense inverse's; entries off
    /// it are refused.
    #[test]
    fn selected_inverse_matches_the_dense_inverse_on_the_pattern() {
        for &(nc, w, nx, seed) in &[(30, 3, 5, 1), (50, 7, 0, 2), (12, 11, 4, 3), (40, 5, 9, 4)] {
            let a = random_arrow(nc, w, nx, seed);
            let inv = dense(&a).llt(Side::Lower).unwrap().inverse();
            let sel = a.factor().unwrap().selected_inverse();
            for i in 0..nc + nx {
                for j in 0..nc + nx {
                    let on = i >= nc || j >= nc || i.abs_diff(j) <= w;
                    match sel.get(i, j) {
                        Some(v) => {
                            assert!(on, "({i}, {j}) is off the pattern");
                            let e = inv[(i, j)];
                            assert!(
                                (v - e).abs() < 1e-9 * (1.0 + e.abs()),
                                "({i}, {j}): {v} vs {e}"
                            );
                        }
                        None => assert!(!on, "({i}, {j}) missing"),
                    }
                }
            }
            assert_eq!(sel.get(nc + nx, 0), None);
        }
    }

    /// The leverage of a local Gram: tr(A⁻¹ G) as the dense product gives.
    #[test]
    fn trace_product_is_the_dense_trace() {
        let (nc, w, nx) = (20, 4, 3);
        let a = random_arrow(nc, w, nx, 7);
        let inv = dense(&a).llt(Side::Lower).unwrap().inverse();
        let sel = a.factor().unwrap().selected_inverse();
        let idx = [6, 7, 8, 9, 10, nc, nc + 2];
        let j = Mat::from_fn(9, idx.len(), |r, c| ((1 + 2 * r + 5 * c) as f64).cos());
        let g = j.transpose() * &j;
        let mut want = 0.0;
        for a in 0..idx.len() {
            for b in 0..idx.len() {
                want += inv[(idx[a], idx[b])] * g[(a, b)];
            }
        }
        let got = sel.trace_product(&idx, g.as_ref()).unwrap();
        assert!(
            (got - want).abs() < 1e-10 * (1.0 + want.abs()),
            "{got} vs {want}"
        );
        assert_eq!(
            sel.trace_product(&[0, 10], Mat::<f64>::identity(2, 2).as_ref()),
            None
        );
    }
}
