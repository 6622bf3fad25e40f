//! The lower triangle of a Gram matrix JᵀJ, the product the assembly of
//! the Gauss–Newton matrix spends most of its time in
//! ([`crate::problem`]: per knot span, a few hundred rows by 50–90 columns).

use faer::{Accum, MatMut, MatRef, Par};

/// Height of the row panels of [`lower_gram`] for `k` rows of J: 8, or 16
/// below 48 rows (where a product's fixed cost weighs more than the
/// diagonal blocks' wasted half; measured at w = 72: k = 20 in 3.6 µs
/// instead of 4.4, k = 120 in 13.8 instead of 14.9).
pub(crate) fn panel_height(k: usize) -> usize {
    if k < 48 {
        16
    } else {
        8
    }
}

/// The lower triangle of `dst` set to (`Accum::Replace`) or increased by
/// (`Accum::Add`) the one of JᵀJ, `j` being k × w and `dst` w × w.
///
/// Row panel by row panel: rows r0..r1 (r1 − r0 ≤ [`panel_height`]) of the lower
/// triangle are J[:, r0..r1]ᵀ J[:, 0..r1], one general matrix product each.
/// The panel's diagonal block is computed whole (its upper part, outside
/// the lower triangle, is overwritten too and is not meant to be read).
/// Measured against faer's triangular product (`BlockStructure::TriangularLower`)
/// at the assembly's shapes on AVX-512: w = 72, k = 120 in 13.8–15.9 µs instead of
/// 20.1–21.8 µs; w = 53 in 9.3 instead of 13.7 µs — the panels run the general
/// kernel on full blocks, and the ≤ 8 × 8 diagonal blocks waste little.
///
/// # Panics
/// If `dst` is not w × w.
#[track_caller]
pub(crate) fn lower_gram(mut dst: MatMut<'_, f64>, accum: Accum, j: MatRef<'_, f64>) {
    let w = j.ncols();
    assert!(dst.nrows() == w && dst.ncols() == w, "Gram block shape");
    let h = panel_height(j.nrows());
    let mut r0 = 0;
    while r0 < w {
        let r1 = (r0 + h).min(w);
        faer::linalg::matmul::matmul(
            dst.as_mut().submatrix_mut(r0, 0, r1 - r0, r1),
            accum,
            j.subcols(r0, r1 - r0).transpose(),
            j.subcols(0, r1),
            1.0,
            Par::Seq,
        );
        r0 = r1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;

    /// Against the sums written out, for widths around the panel height
    /// (one partial panel, exact multiples) and a few row counts; `Add`
    /// adds to what is there, `Replace` ignores it; the strict upper
    /// triangle outside the diagonal panels is left alone.
    #[test]
    fn lower_gram_is_the_lower_triangle_of_jt_j() {
        for &(k, w) in &[
            (1, 1),
            (3, 7),
            (5, 8),
            (9, 9),
            (120, 17),
            (20, 72),
            (7, 53),
            (60, 40),
        ] {
            let j = Mat::<f64>::from_fn(k, w, |r, c| {
                ((r * 31 + c * 17) % 13) as f64 - 6.0 + 0.1 * c as f64
            });
            let exact = |r: usize, c: usize| (0..k).map(|i| j[(i, r)] * j[(i, c)]).sum::<f64>();
            for accum in [Accum::Replace, Accum::Add] {
                let mut dst = Mat::<f64>::from_fn(w, w, |r, c| (r * w + c) as f64);
                lower_gram(dst.as_mut(), accum, j.as_ref());
                for c in 0..w {
                    for r in 0..w {
                        let before = (r * w + c) as f64;
                        let got = dst[(r, c)];
                        if r >= c {
                            let want = exact(r, c)
                                + if matches!(accum, Accum::Add) {
                                    before
                                } else {
                                    0.0
                                };
                            assert!(
                                (got - want).abs() <= 1e-12 * (1.0 + want.abs()),
                                "k {k} w {w} ({r}, {c}): {got} vs {want}"
                            );
                        } else if r / panel_height(k) != c / panel_height(k) {
                            assert_eq!(got, before, "upper ({r}, {c}) touched");
                        }
                    }
                }
            }
        }
    }
}
