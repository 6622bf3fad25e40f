//! Helpers shared by the driver-against-simulator tests.

/// Least-squares fit of `A sin ωτ + B cos ωτ + C`; returns (A, B, C, rms residual).
pub fn fit_sine(ts: &[f64], ys: &[f64], omega: f64) -> (f64, f64, f64, f64) {
    let mut n = [[0.0; 4]; 3];
    for (&t, &y) in ts.iter().zip(ys) {
        let row = [(omega * t).sin(), (omega * t).cos(), 1.0];
        for r in 0..3 {
            for c in 0..3 {
                n[r][c] += row[r] * row[c];
            }
            n[r][3] += row[r] * y;
        }
    }
    // Gauss–Jordan on the 3×3 normal equations.
    for p in 0..3 {
        let piv = n[p][p];
        for c in 0..4 {
            n[p][c] /= piv;
        }
        for r in 0..3 {
            if r != p {
                let f = n[r][p];
                for c in 0..4 {
                    n[r][c] -= f * n[p][c];
                }
            }
        }
    }
    let (a, b, c) = (n[0][3], n[1][3], n[2][3]);
    let ss: f64 = ts
        .iter()
        .zip(ys)
        .map(|(&t, &y)| (y - a * (omega * t).sin() - b * (omega * t).cos() - c).powi(2))
        .sum();
    (a, b, c, (ss / (ts.len() as f64 - 3.0)).sqrt())
}
