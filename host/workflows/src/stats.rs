//! Test statistics of residual sequences shared by the diagnosis and the
//! noise identification: the χ² tail probability and the Ljung–Box
//! whiteness test.

/// Ljung–Box lags.
pub(crate) const LJUNG_BOX_LAGS: usize = 20;

/// Ljung–Box Q over `lags` lags and its p-value (χ² with `lags` dof).
pub fn ljung_box(r: &[f64], lags: usize) -> (f64, f64) {
    let n = r.len();
    if n <= lags + 1 {
        return (0.0, 1.0);
    }
    let m = r.iter().sum::<f64>() / n as f64;
    // centred once; each sum below takes the same terms in the same order
    let d: Vec<f64> = r.iter().map(|v| v - m).collect();
    let c0: f64 = d.iter().map(|v| v * v).sum();
    if c0 <= 0.0 {
        return (0.0, 1.0);
    }
    let mut q = 0.0;
    let mut k = 1;
    while k <= lags {
        let c = lagged_products(&d, k, (lags + 1 - k).min(LAG_BLOCK));
        for (j, ck) in c.iter().enumerate() {
            let rho = ck / c0;
            q += rho * rho / (n - k - j) as f64;
        }
        k += c.len();
    }
    q *= n as f64 * (n as f64 + 2.0);
    (q, chi2_sf(q, lags as f64))
}

/// Lags summed in one pass over the series.
const LAG_BLOCK: usize = 4;

/// Σ_{i≥k} d_i d_{i−k} for the `count` ≤ [`LAG_BLOCK`] lags k0, k0 + 1, …:
/// one pass over the series for all of them, each sum over ascending i (the
/// terms and order of the plain sum per lag). Where the CPU has AVX2 the
/// copy compiled for it runs (four lags in one vector; no FMA, the same bits).
fn lagged_products(d: &[f64], k0: usize, count: usize) -> Vec<f64> {
    #[cfg(target_arch = "x86_64")]
    if robimu_model::lanes::has_avx2() {
        // SAFETY: the CPU has AVX2
        return unsafe { lagged_products_avx2(d, k0, count) };
    }
    lagged_products_of(d, k0, count)
}

/// [`lagged_products`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2")]
unsafe fn lagged_products_avx2(d: &[f64], k0: usize, count: usize) -> Vec<f64> {
    lagged_products_of(d, k0, count)
}

/// [`lagged_products`]' body.
#[inline(always)]
fn lagged_products_of(d: &[f64], k0: usize, count: usize) -> Vec<f64> {
    let n = d.len();
    let mut acc = [-0.0f64; LAG_BLOCK];
    let last = k0 + count - 1;
    // the first terms of the shorter lags, up to where every lag has one
    for i in k0..last.min(n) {
        for (j, a) in acc.iter_mut().enumerate().take(count) {
            if i >= k0 + j {
                *a += d[i] * d[i - k0 - j];
            }
        }
    }
    if count == LAG_BLOCK {
        // the block's sums last lag first: rev[LAG_BLOCK − 1 − j] = acc[j]
        let mut rev = [acc[3], acc[2], acc[1], acc[0]];
        for (w, &di) in d.windows(LAG_BLOCK).zip(d.get(last..).unwrap_or(&[])) {
            // w[LAG_BLOCK − 1 − j] = d_{i−k0−j}
            for (r, x) in rev.iter_mut().zip(w) {
                *r += di * x;
            }
        }
        acc = [rev[3], rev[2], rev[1], rev[0]];
    } else {
        for i in last..n {
            for (j, a) in acc.iter_mut().enumerate().take(count) {
                *a += d[i] * d[i - k0 - j];
            }
        }
    }
    acc[..count].to_vec()
}

/// P(χ²_k > x): the regularised upper incomplete gamma Q(k/2, x/2)
/// (series for x < a+1, Lentz continued fraction otherwise; Numerical
/// Recipes §6.2), evaluated in log space so tiny p-values do not underflow early.
pub(crate) fn chi2_sf(x: f64, k: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let (a, x) = (0.5 * k, 0.5 * x);
    let lg = ln_gamma(a);
    if x < a + 1.0 {
        let (mut sum, mut del, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        1.0 - (sum.ln() - x + a * x.ln() - lg).exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (h.ln() - x + a * x.ln() - lg).exp()
    }
}

/// ln Γ(a), a > 0 (Lanczos, g = 7, n = 9; relative error ~1e-15).
#[allow(clippy::excessive_precision)] // the published coefficients, verbatim
pub(crate) fn ln_gamma(a: f64) -> f64 {
    const G: [f64; 9] = [
        0.99999999999980993,
        676.5203681218851,
        -1259.1392167224028,
        771.32342877765313,
        -176.61502916214059,
        12.507343278686905,
        -0.13857109526572012,
        9.9843695780195716e-6,
        1.5056327351493116e-7,
    ];
    if a < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * a).sin()).ln() - ln_gamma(1.0 - a);
    }
    let a = a - 1.0;
    let mut s = G[0];
    for (i, g) in G.iter().enumerate().skip(1) {
        s += g / (a + i as f64);
    }
    let t = a + 7.5;
    0.5 * (2.0 * std::f64::consts::PI).ln() + (a + 0.5) * t.ln() - t + s.ln()
}
